"""The one training loop of every stage-1 method: data order, checkpoints, exact resume, DDP, logs, previews.

A run folder ``RUN_DIR`` (:class:`dancesynth.core.runs.RunFolder`, kind ``"stage1"``) holds the checkpoint
(``latest.json`` and its ``ckpt-*`` folder), ``metrics.csv`` (one row per epoch: mean of every scalar the
method logs), ``loss.png`` and ``previews/epoch_XXXX.mp4`` (a skeleton video of a validation song).

Exact resume: the data order of epoch ``e`` is a permutation drawn from ``seed`` and ``e`` alone, and a
checkpoint stores the position inside it plus every RNG state and optimizer state, so a run killed at any
point and resumed from its last checkpoint ends with the same weights as an uninterrupted run.

Distributed: ``torchrun --nproc_per_node N -m apps.cli train-pose ...`` starts N processes. Each takes an
equal share of every global batch (``batch_size`` windows in all) and :meth:`Stage1Method.optimize` averages
gradients across processes (:meth:`RunFolder.average_gradients`) before each optimizer step. Only rank 0 writes.
"""

from __future__ import annotations

import dataclasses
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from dancesynth.core.checkpoint import POINTER, checkpoint_files, run_file_contents
from dancesynth.core.config import config_from_dict, config_to_dict
from dancesynth.core.device import resolve_device
from dancesynth.core.errors import DancesynthError
from dancesynth.core.runs import RunFolder, epoch_order
from dancesynth.core.skeleton import body_scale
from stage1_pose.data.dataset import DanceDataset, WindowDataset, collate
from stage1_pose.models.base import Stage1Method
from stage1_pose.registry import build_method, config_type, load_method, make_config

KIND = "stage1"


@dataclass(frozen=True)
class TrainerConfig:
    """Loop settings shared by all methods.

    ``epochs``, ``batch_size`` (global, over all processes) and ``window_frames`` default (None) to the
    method config's values; learning rates live in the method config. ``stride_frames`` is the hop between
    training windows (default half a window). ``checkpoint_every`` is in optimizer steps (a checkpoint is
    also written at the end and when ``minutes`` run out); ``preview_every`` in epochs (0 = never);
    ``preview_seconds`` the length of the preview dance in seconds; a due preview is skipped when the last one
    (or the start of this invocation) is less than ``preview_gap_minutes`` ago, so methods with epochs of a few
    seconds do not spend a third of their time drawing previews. ``loss.png`` is redrawn after an epoch when
    the last drawing is at least ``plot_gap_seconds`` old, and at the end (drawing a dozen panels takes 1-2 s,
    as long as a Dancing2Music epoch). ``minutes`` bounds the run's wall-clock training time in all (every call
    together, :mod:`dancesynth.core.runs`).
    """

    epochs: int | None = None
    batch_size: int | None = None
    window_frames: int | None = None
    stride_frames: int | None = None
    checkpoint_every: int = 200
    preview_every: int = 10
    preview_seconds: float = 20.0
    preview_gap_minutes: float = 2.0
    plot_gap_seconds: float = 60.0
    seed: int = 0
    num_workers: int = 0
    minutes: float | None = None


def _count(value: Any) -> int:
    """A whole number of at least 0 read from a run's metadata; anything else raises (an edited file)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"{value!r} is not a whole number of at least 0")
    return value


def rank_batches(order: list[int], batch_size: int, rank: int, world: int) -> list[list[int]]:
    """This process's share of each global batch of ``batch_size`` windows (incomplete batches dropped)."""
    per_rank = batch_size // world
    full = len(order) // batch_size
    return [order[b * batch_size + rank * per_rank: b * batch_size + (rank + 1) * per_rank] for b in range(full)]


class PoseTrainer:
    """State of one training run (see the module docstring). Use :func:`train`."""

    def __init__(self, method_name: str, data_dir: Path, run: RunFolder, config: Any, options: TrainerConfig,
                 device: torch.device) -> None:
        self.method_name, self.folder, self.options, self.device = method_name, run, options, device
        self.run_dir, self.rank, self.world = run.path, run.rank, run.world
        self.epochs = options.epochs or config.epochs
        # A preset's epoch may be a fixed number of windows, so a small dataset gets as many steps as a large one.
        self.epoch_windows = config.epoch_windows
        self.batch_size = options.batch_size or config.batch_size
        if self.batch_size % self.world:
            raise DancesynthError(f"The batch size {self.batch_size} must be a multiple of the {self.world} "
                                  "processes; change --batch-size or --nproc_per_node.")
        window = options.window_frames or config.window_frames
        # A method config may set its own hop (``stride_frames``; 0 or absent: half a window).
        stride = options.stride_frames or getattr(config, "stride_frames", 0) or max(1, window // 2)
        method_class = load_method(method_name)[0]
        self.data = WindowDataset(data_dir, "train", method_class.feature_kind, window, stride,
                                  progress=self.rank == 0)
        if len(self.data) < self.batch_size:
            raise DancesynthError(f"The training split of {data_dir} gives {len(self.data)} windows of {window} "
                                  f"frames, fewer than one batch of {self.batch_size}; add clips (at least "
                                  f"{window / self.data.dataset.fps:g} s long) or lower --batch-size or "
                                  "--set window_frames=N.")
        self.dataset: DanceDataset = self.data.dataset
        torch.manual_seed(options.seed)  # same initial weights in every process
        self.method: Stage1Method = build_method(method_name, config).to(device)
        self.method._optimizers = self.method.configure_optimizers()
        if self.world > 1:
            self.method._sync_gradients = run.average_gradients
        torch.manual_seed(options.seed + self.rank)  # dropout / noise differ between processes
        self.epoch, self.batch_index, self.step = 0, 0, 0
        self.sums: dict[str, float] = {}
        self.count = 0
        self.meta_base = self._data_meta(config)

    def _data_meta(self, config: Any) -> dict[str, Any]:
        train = self.dataset.clips("train")
        first = self.dataset.load_poses(train[0])
        scales = [body_scale(self.dataset.load_poses(c)) for c in train[:50]]
        stats = self.data.stats
        return {"kind": KIND, "method": self.method_name, "config": config_to_dict(config),
                "feature_kind": self.data.feature_kind, "fps": self.dataset.fps,
                "canvas": [first.width, first.height], "body_scale": float(np.median(scales)),
                "feature_stats": {"mean": stats.mean.tolist(), "std": stats.std.tolist()},
                "styles": list(self.dataset.styles), "seed": self.options.seed, "world_size": self.world,
                "batch_size": self.batch_size, "window_frames": self.data.window_frames,
                "stride_frames": self.data.stride_frames, "data": str(self.dataset.root)}

    # --- checkpoints -------------------------------------------------------------------------------------
    def meta(self) -> dict[str, Any]:
        return {**self.meta_base, "epoch": self.epoch, "batch_index": self.batch_index, "step": self.step,
                "epochs": self.epochs, "curriculum": self.method.curriculum_state()}

    def save(self) -> dict[str, Any]:
        return self.folder.save(self.method, self.meta(), self.method._optimizers,
                                {"sums": dict(self.sums), "count": self.count})

    def restore(self) -> None:
        meta, extra = self.folder.restore(self.method, self.method._optimizers)
        with run_file_contents(self.folder.path / POINTER):
            self.method.load_curriculum_state(meta["curriculum"])
            self.epoch, self.batch_index, self.step = (_count(meta[key]) for key in ("epoch", "batch_index", "step"))
        with run_file_contents(checkpoint_files(self.folder.path, meta)[1]):
            self.sums, self.count = dict(extra["sums"]), int(extra["count"])

    # --- logging -----------------------------------------------------------------------------------------
    def log_epoch(self, seconds: float) -> None:
        self.folder.log("metrics", {"epoch": self.epoch, "step": self.step, "seconds": round(seconds, 3),
                                 **{k: v / max(self.count, 1) for k, v in sorted(self.sums.items())}})

    def preview(self) -> None:
        from dancesynth.core.draw import write_skeleton_video
        from stage1_pose.generate import LoadedPoseModel, generate_from_features

        clips = self.dataset.clips("val") or self.dataset.clips("train")
        clip = clips[0]
        frames = int(self.options.preview_seconds * self.dataset.fps)
        feats = np.asarray(self.dataset.load_features(clip, self.data.feature_kind)[:frames])
        samples = self.dataset.load_audio(clip)[: int(frames / self.dataset.fps * self.dataset.sample_rate)]
        loaded = LoadedPoseModel(self.method, self.meta(), self.device)
        was_training = self.method.training
        seq = generate_from_features(loaded, feats, self.dataset.load_beats(clip)["beats"], seed=0)
        self.method.train(was_training)
        folder = self.run_dir / "previews"
        folder.mkdir(exist_ok=True)
        # Half the canvas: previews are for a glance and must not slow training down.
        write_skeleton_video(seq, folder / f"epoch_{self.epoch:04d}.mp4", audio=samples,
                             audio_sr=self.dataset.sample_rate, size=(seq.width // 2, seq.height // 2))

    # --- the loop ----------------------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        """Train to ``epochs`` or until ``minutes`` are spent, then checkpoint; returns the final metadata.
        Ctrl-C or SIGTERM saves, then raises :class:`KeyboardInterrupt` (:meth:`RunFolder.training`)."""
        opts = self.options
        last_preview = last_plot = time.monotonic()
        self.method.train()
        steps_per_epoch = (self.epoch_windows or len(self.data)) // self.batch_size
        with self.folder.training(self.save, opts.minutes, self.epochs * steps_per_epoch, self.step,
                                  f"{self.method_name} training") as session:
            while self.epoch < self.epochs and not session.stopped:
                started = time.monotonic()
                order = epoch_order(len(self.data), opts.seed, self.epoch, self.epoch_windows)
                batches = rank_batches(order, self.batch_size, self.rank, self.world)
                # Its own generator: a DataLoader iterator otherwise draws a seed from the global RNG, which would
                # make a resumed run's dropout/noise differ from the uninterrupted run's.
                loader = torch.utils.data.DataLoader(self.data, batch_sampler=batches[self.batch_index:],
                                                     collate_fn=collate, num_workers=opts.num_workers,
                                                     generator=torch.Generator().manual_seed(opts.seed))
                for batch in loader:
                    logs = self.method.training_step(batch.to(self.device), self.epoch)
                    for k, v in logs.items():
                        self.sums[k] = self.sums.get(k, 0.0) + float(v)
                    self.count += 1
                    self.batch_index += 1
                    self.step += 1
                    if self.step % opts.checkpoint_every == 0:
                        self.save()
                    if session.step_done(self.step, epoch=self.epoch + 1, **{k: f"{v:.4f}" for k, v in logs.items()}):
                        break
                if self.batch_index < len(batches):
                    break  # stopped inside the epoch: its row is logged when a resumed run ends it
                self.log_epoch(time.monotonic() - started)
                if time.monotonic() - last_plot >= opts.plot_gap_seconds:
                    self.folder.plot("loss.png")
                    last_plot = time.monotonic()
                self.epoch, self.batch_index, self.sums, self.count = self.epoch + 1, 0, {}, 0
                if (opts.preview_every and self.epoch % opts.preview_every == 0 and self.rank == 0
                        and time.monotonic() - last_preview >= opts.preview_gap_minutes * 60):
                    self.preview()
                    last_preview = time.monotonic()
        meta = self.save()
        self.folder.plot("loss.png")
        self.folder.close()
        return meta


def train(method_name: str, data_dir: str | os.PathLike, out_dir: str | os.PathLike, preset: str = "small",
          epochs: int | None = None, resume: bool = False, device: str = "auto",
          overrides: dict[str, Any] | None = None, minutes: float | None = None,
          options: TrainerConfig | None = None) -> dict[str, Any]:
    """Train (or with ``resume`` continue) method ``method_name`` on the dataset ``data_dir`` into run folder
    ``out_dir``; returns the final checkpoint's metadata.

    ``overrides`` change fields of the method's ``preset`` config (ignored on resume: the run's own config is
    used). ``epochs`` / ``minutes`` override ``options``; both are totals over every call, so resuming with a
    larger value extends a finished run.
    """
    options = options or TrainerConfig()
    options = dataclasses.replace(options, epochs=epochs or options.epochs,
                                  minutes=minutes if minutes is not None else options.minutes)
    dev = resolve_device(device)
    run = RunFolder(out_dir, KIND, dev, resume=resume)
    if run.meta is not None:
        meta = run.meta
        if meta.get("method") != method_name:
            raise DancesynthError(f"{run.path} is a {meta.get('method')} run; resume it with --method "
                                  f"{meta.get('method')}.")
        with run_file_contents(run.path / POINTER):
            config = config_from_dict(config_type(method_name), meta["config"])
            saved = {key: _count(meta[key])
                     for key in ("epochs", "seed", "batch_size", "window_frames", "stride_frames")}
            if min(value for key, value in saved.items() if key != "seed") < 1:
                raise ValueError("epochs, batch_size, window_frames and stride_frames must be positive")
        options = dataclasses.replace(options, epochs=options.epochs or saved["epochs"], seed=saved["seed"],
                                      batch_size=saved["batch_size"], window_frames=saved["window_frames"],
                                      stride_frames=saved["stride_frames"])
    else:
        config = make_config(method_name, preset, overrides)
    trainer = PoseTrainer(method_name, Path(data_dir), run, config, options, dev)
    if resume:
        trainer.restore()
    return trainer.run()
