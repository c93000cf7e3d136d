"""The one training loop of every stage-1 method: data order, checkpoints, exact resume, DDP, logs, previews.

A run folder ``RUN_DIR`` holds ``latest.safetensors`` / ``latest.json`` / ``latest.training.pt``
(:mod:`dancesynth.core.checkpoint`, kind ``"stage1"``), ``metrics.csv`` (one row per epoch: mean of every
scalar the method logs), ``loss.png`` and ``previews/epoch_XXXX.mp4`` (a skeleton video of a validation song).

Exact resume: the data order of epoch ``e`` is a permutation drawn from ``seed`` and ``e`` alone, and a
checkpoint stores the position inside it plus every RNG state and optimizer state, so a run killed at any
point and resumed from its last checkpoint ends with the same weights as an uninterrupted run.

Distributed: ``torchrun --nproc_per_node N -m apps.cli train-pose ...`` starts N processes (gloo on CPU, nccl
on GPU). Each takes an equal share of every global batch (``batch_size`` windows in all) and
:meth:`Stage1Method.optimize` averages gradients across processes before each optimizer step. That is
DistributedDataParallel's arithmetic without its wrapper, which assumes one forward and one backward per
step and so does not fit GAN methods that step several optimizers per batch. Only rank 0 writes.
"""

from __future__ import annotations

import csv
import dataclasses
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.distributed as dist  # noqa: E402
from tqdm import tqdm  # noqa: E402

from dancesynth.core import checkpoint as ckpt  # noqa: E402
from stage1_pose.data.dataset import DanceDataset, WindowDataset, collate  # noqa: E402
from dancesynth.core.device import resolve_device  # noqa: E402
from dancesynth.core.errors import DancesynthError  # noqa: E402
from dancesynth.core.fileio import atomic_path  # noqa: E402
from stage1_pose.registry import build_method, config_from_dict, load_method, make_config  # noqa: E402
from stage1_pose.models.base import Stage1Method  # noqa: E402
from dancesynth.core.skeleton import body_scale  # noqa: E402

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
    as long as a Dancing2Music epoch). ``minutes`` bounds this invocation's wall-clock time.
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


def _distributed(device: torch.device) -> tuple[int, int]:
    """(rank, world size), joining the process group when started by torchrun."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world == 1:
        return 0, 1
    if not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    return dist.get_rank(), world


def _average_gradients(world: int):
    def sync(params: list[torch.nn.Parameter]) -> None:
        grads = [p.grad for p in params if p.grad is not None]
        if not grads:
            return
        flat = torch.cat([g.reshape(-1) for g in grads])
        dist.all_reduce(flat)
        flat /= world
        offset = 0
        for g in grads:
            g.copy_(flat[offset:offset + g.numel()].view_as(g))
            offset += g.numel()
    return sync


def epoch_order(num_items: int, seed: int, epoch: int) -> list[int]:
    """The shuffled window order of ``epoch``: depends only on ``seed`` and ``epoch`` (exact resume)."""
    g = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
    return torch.randperm(num_items, generator=g).tolist()


def rank_batches(order: list[int], batch_size: int, rank: int, world: int) -> list[list[int]]:
    """This process's share of each global batch of ``batch_size`` windows (incomplete batches dropped)."""
    per_rank = batch_size // world
    full = len(order) // batch_size
    return [order[b * batch_size + rank * per_rank: b * batch_size + (rank + 1) * per_rank] for b in range(full)]


class Trainer:
    """State of one training run (see the module docstring). Use :func:`train`."""

    def __init__(self, method_name: str, data_dir: Path, run_dir: Path, config: Any, options: TrainerConfig,
                 device: torch.device) -> None:
        self.method_name, self.run_dir, self.options, self.device = method_name, run_dir, options, device
        self.rank, self.world = _distributed(device)
        self.epochs = options.epochs or config.epochs
        self.batch_size = options.batch_size or config.batch_size
        if self.batch_size % self.world:
            raise DancesynthError(f"The batch size {self.batch_size} must be a multiple of the {self.world} "
                                  "processes; change --batch-size or --nproc_per_node.")
        window = options.window_frames or config.window_frames
        stride = options.stride_frames or max(1, window // 2)
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
            self.method._sync_gradients = _average_gradients(self.world)
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
        return {"kind": KIND, "method": self.method_name, "config": dataclasses.asdict(config),
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

    def save(self) -> None:
        rng = ckpt.capture_rng_state()
        if self.world > 1:
            states: list[Any] = [None] * self.world
            dist.all_gather_object(states, rng)
        else:
            states = [rng]
        if self.rank != 0:
            return
        state = {"optimizers": {k: o.state_dict() for k, o in self.method._optimizers.items()},
                 "rng": states, "sums": dict(self.sums), "count": self.count}
        ckpt.save_checkpoint(self.run_dir, self.method, self.meta(), state)

    def restore(self) -> None:
        state_dict, meta = ckpt.load_checkpoint(self.run_dir, KIND)
        self.method.load_state_dict(state_dict)
        training = ckpt.load_training_state(self.run_dir)
        for name, opt in self.method._optimizers.items():
            opt.load_state_dict(training["optimizers"][name])
        if len(training["rng"]) != self.world:
            raise DancesynthError(f"{self.run_dir} was trained with {len(training['rng'])} processes; resume it "
                                  "with the same number so the continuation is exact.")
        ckpt.restore_rng_state(training["rng"][self.rank])
        self.method.load_curriculum_state(meta["curriculum"])
        self.epoch, self.batch_index, self.step = meta["epoch"], meta["batch_index"], meta["step"]
        self.sums, self.count = dict(training["sums"]), int(training["count"])
        if self.rank == 0:
            _drop_rows_from(self.run_dir / "metrics.csv", self.epoch)

    # --- logging -----------------------------------------------------------------------------------------
    def log_epoch(self, seconds: float) -> None:
        row = {"epoch": self.epoch, "step": self.step, "seconds": round(seconds, 3),
               **{k: v / max(self.count, 1) for k, v in sorted(self.sums.items())}}
        path = self.run_dir / "metrics.csv"
        _append_metrics(path, row)
        if self.tensorboard is not None:
            for k, v in row.items():
                if k not in ("epoch", "step"):
                    self.tensorboard.add_scalar(k, v, self.epoch)

    def plot(self) -> None:
        """Redraw ``loss.png`` from ``metrics.csv`` (nothing before the first logged epoch)."""
        path = self.run_dir / "metrics.csv"
        if path.is_file():
            plot_metrics(path, self.run_dir / "loss.png")

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
        seq = generate_from_features(loaded, feats, seed=0)
        self.method.train(was_training)
        folder = self.run_dir / "previews"
        folder.mkdir(exist_ok=True)
        # Half the canvas: previews are for a glance and must not slow training down.
        write_skeleton_video(seq, folder / f"epoch_{self.epoch:04d}.mp4", audio=samples,
                             audio_sr=self.dataset.sample_rate, size=(seq.width // 2, seq.height // 2))

    # --- the loop ----------------------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        opts = self.options
        self.tensorboard = _tensorboard(self.run_dir) if self.rank == 0 else None
        deadline = None if opts.minutes is None else time.monotonic() + opts.minutes * 60
        last_preview = last_plot = time.monotonic()
        self.method.train()
        stopped = False
        while self.epoch < self.epochs and not stopped:
            started = time.monotonic()
            batches = rank_batches(epoch_order(len(self.data), opts.seed, self.epoch), self.batch_size,
                                   self.rank, self.world)
            # Its own generator: a DataLoader iterator otherwise draws a seed from the global RNG, which would
            # make a resumed run's dropout/noise differ from the uninterrupted run's.
            loader = torch.utils.data.DataLoader(self.data, batch_sampler=batches[self.batch_index:],
                                                 collate_fn=collate, num_workers=opts.num_workers,
                                                 generator=torch.Generator().manual_seed(opts.seed))
            bar = tqdm(loader, desc=f"{self.method_name} epoch {self.epoch + 1}/{self.epochs}", unit="batch",
                       initial=self.batch_index, total=len(batches), disable=self.rank != 0, leave=False)
            for batch in bar:
                logs = self.method.training_step(batch.to(self.device), self.epoch)
                for k, v in logs.items():
                    self.sums[k] = self.sums.get(k, 0.0) + float(v)
                self.count += 1
                self.batch_index += 1
                self.step += 1
                bar.set_postfix({k: f"{v:.4f}" for k, v in logs.items()})
                if self.step % opts.checkpoint_every == 0:
                    self.save()
                if deadline is not None and _agree(time.monotonic() > deadline, self.world):
                    stopped = self.batch_index < len(batches)
                    break
            if stopped:
                break
            if self.rank == 0:
                self.log_epoch(time.monotonic() - started)
                if time.monotonic() - last_plot >= opts.plot_gap_seconds:
                    self.plot()
                    last_plot = time.monotonic()
            self.epoch, self.batch_index, self.sums, self.count = self.epoch + 1, 0, {}, 0
            if (opts.preview_every and self.epoch % opts.preview_every == 0 and self.rank == 0
                    and time.monotonic() - last_preview >= opts.preview_gap_minutes * 60):
                self.preview()
                last_preview = time.monotonic()
        self.save()
        if self.rank == 0:
            self.plot()
        if self.tensorboard is not None:
            self.tensorboard.close()
        return self.meta()


def _append_metrics(csv_path: Path, row: dict[str, Any]) -> None:
    """Append ``row`` to ``metrics.csv``. A row with new columns (a method's second training phase logs other
    losses) rewrites the file with the union of columns, leaving them empty in earlier rows."""
    fields: list[str] = []
    rows: list[dict[str, str]] = []
    if csv_path.is_file():
        with open(csv_path, newline="") as f:
            reader = csv.DictReader(f)
            fields = list(reader.fieldnames or [])
            if set(row) <= set(fields):
                with open(csv_path, "a", newline="") as out:
                    csv.DictWriter(out, fieldnames=fields, restval="").writerow(row)
                return
            rows = list(reader)
    fields += [k for k in row if k not in fields]
    with atomic_path(csv_path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields, restval="")
        writer.writeheader()
        writer.writerows([*rows, row])


def _drop_rows_from(csv_path: Path, epoch: int) -> None:
    """Forget metrics rows of epochs >= ``epoch``: a killed run may have logged past its last checkpoint."""
    if not csv_path.is_file():
        return
    with open(csv_path, newline="") as f:
        reader = csv.DictReader(f)
        fields, rows = reader.fieldnames, [r for r in reader if int(r["epoch"]) < epoch]
    with atomic_path(csv_path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)


def _agree(flag: bool, world: int) -> bool:
    """True in every process when it is True in rank 0 (so all processes stop at the same step)."""
    if world == 1:
        return flag
    t = torch.tensor([1.0 if flag else 0.0])
    dist.broadcast(t, 0)
    return bool(t.item())


def _tensorboard(run_dir: Path):
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError:  # the tensorboard package is optional: metrics.csv and loss.png always exist
        return None
    return SummaryWriter(str(run_dir / "tensorboard"))


def plot_metrics(csv_path: Path, png_path: Path) -> None:
    """Plot every column of ``metrics.csv`` against epoch into ``png_path`` (one panel per scalar)."""
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    keys = [k for k in (rows[0] if rows else {}) if k not in ("epoch", "step", "seconds")]
    if not keys:
        return
    fig, axes = plt.subplots(len(keys), 1, figsize=(6, 2.2 * len(keys)), squeeze=False, sharex=True)
    epochs = [int(r["epoch"]) + 1 for r in rows]
    for ax, key in zip(axes[:, 0], keys):
        ax.plot(epochs, [float(r[key]) if r.get(key) else np.nan for r in rows])
        ax.set_ylabel(key)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("epoch")
    fig.tight_layout()
    with atomic_path(png_path) as tmp:
        fig.savefig(tmp, dpi=80)
    plt.close(fig)


def train(method_name: str, data_dir: str | os.PathLike, out_dir: str | os.PathLike, preset: str = "small",
          epochs: int | None = None, resume: bool = False, device: str = "auto",
          overrides: dict[str, Any] | None = None, minutes: float | None = None,
          options: TrainerConfig | None = None) -> dict[str, Any]:
    """Train (or with ``resume`` continue) method ``method_name`` on the dataset ``data_dir`` into run folder
    ``out_dir``; returns the final checkpoint's metadata.

    ``overrides`` change fields of the method's ``preset`` config (ignored on resume: the run's own config is
    used). ``epochs`` / ``minutes`` override ``options``; ``epochs`` is the total, so resuming with a larger
    value extends a finished run.
    """
    options = options or TrainerConfig()
    options = dataclasses.replace(options, epochs=epochs or options.epochs,
                                  minutes=minutes if minutes is not None else options.minutes)
    run_dir = Path(out_dir)
    dev = resolve_device(device)
    if resume:
        meta = ckpt.load_meta(run_dir, KIND)
        if meta["method"] != method_name:
            raise DancesynthError(f"{run_dir} is a {meta['method']} run; resume it with --method {meta['method']}.")
        config = config_from_dict(type(next(iter(load_method(method_name)[1].values()))), meta["config"])
        options = dataclasses.replace(options, epochs=options.epochs or meta["epochs"], seed=meta["seed"],
                                      batch_size=meta["batch_size"], window_frames=meta["window_frames"],
                                      stride_frames=meta["stride_frames"])
    else:
        if (run_dir / "latest.json").is_file():
            raise DancesynthError(f"{run_dir} already holds a trained model; pass --resume to continue it "
                                  "or choose a new --out folder.")
        config = make_config(method_name, preset, overrides)
    trainer = Trainer(method_name, Path(data_dir), run_dir, config, options, dev)
    if trainer.rank == 0:
        run_dir.mkdir(parents=True, exist_ok=True)
    if resume:
        trainer.restore()
    return trainer.run()
