"""Pose-sequence style classifier: the feature extractor behind FID, ACC, diversity and multimodality.

As in Dance Revolution: an LSTM (hidden 200) reads a pose sequence and a linear layer gives logits over the
dataset's styles; the time-averaged LSTM output is the 200-d feature. It reads fixed windows
(``window_frames``, 4 s at 15 fps by default); a whole dance is cut into consecutive windows, so a dance
gets one feature per window (for the long-term FID curve) and their mean as its feature.

Input per frame: :func:`dancesynth.core.skeleton.normalize` model coordinates (root position relative to the
canvas centre and joints relative to the root, in torso lengths) and their frame-to-frame velocity, 100 values.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from dancesynth.core.checkpoint import POINTER, checkpoint_files, load_checkpoint, run_file_contents
from dancesynth.core.config import config_from_dict, config_to_dict
from dancesynth.core.device import resolve_device
from dancesynth.core.errors import DancesynthError
from dancesynth.core.runs import RunFolder
from dancesynth.core.skeleton import NUM_JOINTS, PoseSequence, normalize

KIND = "style_classifier"
INPUT_DIM = NUM_JOINTS * 2 * 2


@dataclass(frozen=True)
class StyleClassifierConfig:
    """Network size and training schedule.

    ``window_frames`` is in pose frames; ``steps`` counts optimiser updates of ``batch_size`` windows.
    """

    hidden: int = 200
    layers: int = 1
    window_frames: int = 60
    batch_size: int = 64
    steps: int = 300
    lr: float = 1e-3


PRESETS: dict[str, StyleClassifierConfig] = {
    "paper": StyleClassifierConfig(),
    "small": StyleClassifierConfig(hidden=32, window_frames=30, batch_size=32, steps=150, lr=3e-3),
}


class StyleClassifier(nn.Module):
    """``[B, T, INPUT_DIM]`` pose features -> (logits ``[B, styles]``, feature ``[B, hidden]``)."""

    def __init__(self, config: StyleClassifierConfig, num_styles: int) -> None:
        super().__init__()
        self.config = config
        self.lstm = nn.LSTM(INPUT_DIM, config.hidden, num_layers=config.layers, batch_first=True)
        self.head = nn.Linear(config.hidden, num_styles)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out, _ = self.lstm(x)
        feature = out.mean(dim=1)
        return self.head(feature), feature


@contextlib.contextmanager
def _one_cpu_thread(device: torch.device) -> Iterator[None]:
    """Run torch single-threaded on CPU, then restore the thread count.

    LSTM steps this small are latency-bound: extra intra-op threads only add synchronisation (measured 60x
    slower with 2 threads than with 1 on a busy 2-core machine).
    """
    threads = torch.get_num_threads()
    if device.type == "cpu":
        torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def pose_features(seq: PoseSequence) -> np.ndarray:
    """``[T, 100]`` float32 classifier input: normalised coordinates ``[T, 50]`` and their velocity ``[T, 50]``
    (per frame, model units; the first frame's velocity is 0)."""
    xy, _ = normalize(seq)
    flat = xy.reshape(len(seq), -1)
    vel = np.diff(flat, axis=0, prepend=flat[:1])
    return np.concatenate([flat, vel], axis=1).astype(np.float32)


def cut_windows(features: np.ndarray, window_frames: int) -> np.ndarray:
    """``[T, F]`` -> ``[T // window_frames, window_frames, F]`` consecutive windows (the tail is dropped)."""
    n = len(features) // window_frames
    if n == 0:
        raise DancesynthError(f"A dance of {len(features)} frames is shorter than the style classifier's window "
                              f"of {window_frames} frames; evaluate longer dances (raise --seconds).")
    return features[: n * window_frames].reshape(n, window_frames, features.shape[1])


@dataclass
class LoadedStyleClassifier:
    """A trained classifier with what is needed to use it: style names and the feature standardisation."""

    model: StyleClassifier
    styles: list[str]
    mean: np.ndarray
    std: np.ndarray
    device: torch.device

    @property
    def window_frames(self) -> int:
        return self.model.config.window_frames

    @torch.no_grad()
    def embed_windows(self, seq: PoseSequence) -> tuple[np.ndarray, np.ndarray]:
        """Per consecutive window: logits ``[W, styles]`` and features ``[W, hidden]`` (float64)."""
        x = (cut_windows(pose_features(seq), self.window_frames) - self.mean) / self.std
        self.model.eval()
        with _one_cpu_thread(self.device):
            logits, feats = self.model(torch.from_numpy(x.astype(np.float32)).to(self.device))
        return logits.cpu().double().numpy(), feats.cpu().double().numpy()

    def embed(self, seq: PoseSequence) -> tuple[int, np.ndarray, np.ndarray]:
        """(predicted style index, dance feature ``[hidden]``, window features ``[W, hidden]``).

        The dance's prediction is the argmax of its windows' mean logits; its feature the mean window feature.
        """
        logits, feats = self.embed_windows(seq)
        return int(logits.mean(axis=0).argmax()), feats.mean(axis=0), feats


@dataclass
class _Position:
    """How far a training got: optimiser ``step``s, and the loss summed over the ``count`` steps since the last
    ``metrics.csv`` row."""

    step: int = 0
    loss_sum: float = 0.0
    count: int = 0


def train_style_classifier(dances: list[PoseSequence], labels: list[int], styles: list[str],
                           config: StyleClassifierConfig, device: torch.device, run: RunFolder, seed: int = 0,
                           checkpoint_every: int = 50, minutes: float | None = None) -> LoadedStyleClassifier:
    """Train on random ``window_frames`` crops of labelled dances (label = index into ``styles``) into the run
    folder ``run`` (kind ``style_classifier``).

    Cross-entropy, Adam; inputs standardised per dimension with statistics of all training frames. A checkpoint
    is written every ``checkpoint_every`` steps and at the end, each with a ``metrics.csv`` row (mean loss since
    the previous one); a run opened for resume continues exactly from its last checkpoint (``config.steps`` is
    the total, ``minutes`` the wall-clock training time in all). Ctrl-C or SIGTERM saves, then raises
    :class:`KeyboardInterrupt` (:meth:`~dancesynth.core.runs.RunFolder.training`).
    """
    if len(dances) != len(labels) or not dances:
        raise DancesynthError("The style classifier needs at least one labelled dance; "
                              "check the dataset's train split.")
    feats = [pose_features(d) for d in dances]
    w = config.window_frames
    usable = [i for i, f in enumerate(feats) if len(f) >= w]
    if not usable:
        raise DancesynthError(f"Every training dance is shorter than the classifier window ({w} frames); "
                              "build a dataset with longer clips.")
    stacked = np.concatenate(feats, axis=0)
    mean, std = stacked.mean(axis=0), stacked.std(axis=0) + 1e-6
    rng = np.random.default_rng(seed)
    torch.manual_seed(seed)
    model = StyleClassifier(config, len(styles)).to(device)
    opt = torch.optim.Adam(model.parameters(), lr=config.lr)
    clf = LoadedStyleClassifier(model, list(styles), mean, std, device)
    at = _Position()
    if run.resumed:
        meta, extra = run.restore(model, {"adam": opt})
        with run_file_contents(checkpoint_files(run.path, meta)[1]):
            at = _Position(int(meta["step"]), float(extra.get("loss_sum", 0.0)), int(extra.get("count", 0)))
            rng.bit_generator.state = extra["crops"]

    def save() -> dict[str, Any]:
        return run.save(model, {**_meta(clf), "step": at.step, "seed": seed}, {"adam": opt},
                        {"crops": rng.bit_generator.state, "loss_sum": at.loss_sum, "count": at.count})

    y_all = np.asarray(labels, dtype=np.int64)
    model.train()
    with _one_cpu_thread(device), run.training(save, minutes, config.steps, at.step, "style classifier") as session:
        while at.step < config.steps and not session.stopped:
            clip = rng.choice(usable, size=config.batch_size)
            x = np.stack([feats[c][s: s + w] for c, s in
                          ((c, rng.integers(0, len(feats[c]) - w + 1)) for c in clip)])
            xb = torch.from_numpy(((x - mean) / std).astype(np.float32)).to(device)
            logits, _ = model(xb)
            loss = nn.functional.cross_entropy(logits, torch.from_numpy(y_all[clip]).to(device))
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            at.step, at.loss_sum, at.count = at.step + 1, at.loss_sum + loss.item(), at.count + 1
            session.step_done(at.step, loss=f"{loss.item():.3f}")
            if at.step % checkpoint_every == 0 or at.step == config.steps:
                run.log("metrics", {"step": at.step, "loss": at.loss_sum / at.count})
                at.loss_sum, at.count = 0.0, 0
                save()
    if at.count:
        save()  # the budget ran out between two checkpoints
    run.plot("loss.png")
    run.close()
    return clf


def _meta(clf: LoadedStyleClassifier) -> dict[str, Any]:
    """What loading needs besides the weights: config, style names and input statistics."""
    return {"kind": KIND, "config": config_to_dict(clf.model.config), "styles": clf.styles,
            "input_mean": clf.mean.tolist(), "input_std": clf.std.tolist()}


def load_style_classifier(run_dir: str | os.PathLike, device: torch.device) -> LoadedStyleClassifier:
    """The classifier a :func:`train_on_dataset` run folder holds."""
    state, meta = load_checkpoint(run_dir, KIND)
    with run_file_contents(Path(run_dir) / POINTER):
        model = StyleClassifier(config_from_dict(StyleClassifierConfig, meta["config"]), len(meta["styles"]))
        model.load_state_dict(state)
        styles, mean, std = list(meta["styles"]), np.asarray(meta["input_mean"]), np.asarray(meta["input_std"])
    return LoadedStyleClassifier(model.to(device), styles, mean, std, device)


def classifier_accuracy(clf: LoadedStyleClassifier, dances: list[PoseSequence], labels: list[int]) -> float:
    """Share of dances whose predicted style equals the label (e.g. on the test split)."""
    return float(np.mean([clf.embed(d)[0] == y for d, y in zip(dances, labels)]))


def train_on_dataset(data_dir: str | os.PathLike, out_dir: str | os.PathLike, preset: str = "paper",
                     steps: int | None = None, minutes: float | None = None, seed: int = 0, device: str = "auto",
                     resume: bool = False) -> tuple[LoadedStyleClassifier, float]:
    """Train on the dance of every train-split clip of a dataset folder, labelled with the clip's style, into the
    run folder ``out_dir`` (:func:`train_style_classifier`) at ``preset``; ``steps`` replaces its total. With
    ``resume`` the run continues exactly, with its own config and seed.

    Returns the classifier and its accuracy on the real dances of the test split (NaN when it has none),
    which is the ceiling the ACC of generated dances can be read against; the final checkpoint's metadata also
    holds that accuracy and the dataset.
    """
    from stage1_pose.data.dataset import DanceDataset

    dev = resolve_device(device)
    run = RunFolder(out_dir, KIND, dev, resume=resume)
    with run_file_contents(run.path / POINTER):
        config = PRESETS[preset] if run.meta is None else config_from_dict(StyleClassifierConfig, run.meta["config"])
        seed = seed if run.meta is None else int(run.meta["seed"])
    if steps is not None:
        config = dataclasses.replace(config, steps=steps)
    ds = DanceDataset(data_dir)
    train, test = ds.clips("train"), ds.clips("test")
    clf = train_style_classifier([ds.load_poses(c) for c in train], [ds.style_index(c) for c in train],
                                 list(ds.styles), config, dev, run, seed, minutes=minutes)
    accuracy = (classifier_accuracy(clf, [ds.load_poses(c) for c in test], [ds.style_index(c) for c in test])
                if test else float("nan"))
    run.update_meta({"test_accuracy": accuracy, "data": str(data_dir)})
    return clf, accuracy
