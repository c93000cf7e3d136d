"""The run folder protocol every trainer follows: refuse to overwrite, checkpoint, resume exactly, log, plot, DDP.

A trainer opens its ``--out`` folder as a :class:`RunFolder` (in every process when distributed), then

* ``run.restore(model, optimizers)`` when resuming: weights, optimizer states, this process's RNG states and
  the trainer's own extra state (data position, curriculum, generators) come back as they were saved, and
  every metrics table loses the rows written after that checkpoint (a killed run logs past it);
* ``run.log(table, row)`` appends a row to ``TABLE.csv`` (and to TensorBoard event files under
  ``tensorboard/`` when the ``tensorboard`` package is installed);
* ``run.save(model, meta, optimizers, extra)`` writes a checkpoint that survives ``kill -9`` at any instant
  (:mod:`dancesynth.core.checkpoint`); it records how many rows each table has, so resume is exact;
* ``run.plot(name)`` draws every table's curves into one PNG; ``run.close()`` at the end.

The loop itself runs inside ``with run.training(save, minutes, total_steps, step, desc) as session`` and calls
``session.step_done(step, ...)`` after every optimiser step, leaving the loop when it returns True. That gives
every trainer the same behaviour:

* **Time budget**: ``minutes`` is the run's wall-clock training time *in all*, over every call, like ``epochs``
  and ``steps`` are totals: each checkpoint records ``trained_seconds``, and a resumed run trains only what its
  budget has left (none: no step), so an interrupted call re-run with the same flags ends where an
  uninterrupted one would.
* **Ctrl-C and SIGTERM**: the first signal stops the loop after the step it interrupts (the second raises at
  once, :mod:`dancesynth.core.interrupts`); ``save()`` writes a checkpoint, then :class:`KeyboardInterrupt`
  propagates (the CLI exits 130). ``--resume`` continues from that step exactly.
* **Progress**: one counter over the run, seconds of the budget with ``minutes`` (so "left" is the budget's),
  else steps (left estimated from the step rate), with the step and the values the trainer shows.
* **Several processes** stop at the same step: rank 0's decision is everyone's (:meth:`RunFolder.agree`).

Distributed training (``torchrun``): the folder joins the process group from the environment (gloo on CPU,
nccl on GPU); :meth:`RunFolder.average_gradients` averages gradients over processes (DistributedDataParallel's
arithmetic without its wrapper, which assumes one backward per step and so does not fit GANs). ``save`` is
collective (each process's RNG state is kept); only rank 0 writes files; ``close`` leaves the group (all
processes together).
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import torch
import torch.distributed as dist
from torch import nn

from dancesynth.core import checkpoint as ckpt
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.interrupts import StopRequest, deferred_interrupts
from dancesynth.core.plots import plot_metrics
from dancesynth.core.progress import Progress, track


def init_distributed(device: torch.device) -> tuple[int, int]:
    """(rank, world size), joining the process group when started by torchrun (``WORLD_SIZE`` > 1)."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world == 1:
        return 0, 1
    if not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    return dist.get_rank(), world


def average_gradients(params: Iterable[nn.Parameter], world: int) -> None:
    """Replace each gradient by its mean over the ``world`` processes (one all-reduce for all of them)."""
    grads = [p.grad for p in params if p.grad is not None]
    if world == 1 or not grads:
        return
    flat = torch.cat([g.reshape(-1) for g in grads])
    dist.all_reduce(flat)
    flat /= world
    offset = 0
    for g in grads:
        g.copy_(flat[offset:offset + g.numel()].view_as(g))
        offset += g.numel()


def epoch_order(num_items: int, seed: int, epoch: int, length: int = 0) -> list[int]:
    """The shuffled item order of ``epoch``: depends only on ``seed`` and ``epoch``, so a resumed run finds its
    place in it again. ``length`` items (0: ``num_items``, one pass), in fresh permutations as often as needed."""
    g = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
    order: list[int] = []
    while len(order) < max(length, 1):
        order += torch.randperm(num_items, generator=g).tolist()
    return order[:length or num_items]


def append_row(csv_path: Path, row: dict[str, Any]) -> None:
    """Append ``row`` to a CSV. A row with new columns (a second training phase logs other losses) rewrites
    the file with the union of columns, leaving them empty in earlier rows."""
    fields: list[str] = []
    rows: list[dict[str, str]] = []
    if csv_path.is_file():
        with open(csv_path, newline="") as f:
            reader = csv.DictReader(f)
            fields = list(reader.fieldnames or [])
            if fields and set(row) <= set(fields):
                with open(csv_path, "a", newline="") as out:
                    csv.DictWriter(out, fieldnames=fields, restval="").writerow(row)
                return
            rows = list(reader)
    fields += [k for k in row if k not in fields]
    with atomic_path(csv_path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields, restval="")
        writer.writeheader()
        writer.writerows([*rows, row])


def count_rows(csv_path: Path) -> int:
    """Number of data rows of a CSV (0 when it does not exist)."""
    if not csv_path.is_file():
        return 0
    with open(csv_path, newline="") as f:
        return sum(1 for _ in csv.DictReader(f))


def keep_rows(csv_path: Path, count: int) -> None:
    """Keep the header and the first ``count`` rows of a CSV (delete it when ``count`` is 0)."""
    if count == 0:
        csv_path.unlink(missing_ok=True)
        return
    if count_rows(csv_path) <= count:
        return
    with open(csv_path, newline="") as f:
        reader = csv.reader(f)
        kept = [row for _, row in zip(range(count + 1), reader)]
    with atomic_path(csv_path) as tmp, open(tmp, "w", newline="") as f:
        csv.writer(f).writerows(kept)


class RunFolder:
    """One training run's output folder (see the module docstring).

    Opening it with ``resume=False`` refuses a folder that already holds a checkpoint and starts the
    ``tables`` (metrics CSV names without ``.csv``) empty; with ``resume=True`` the folder must hold a
    checkpoint of ``kind``, whose metadata is :attr:`meta`. Rank 0 creates the folder and deletes what
    interrupted saves left behind.
    """

    def __init__(self, path: str | os.PathLike, kind: str, device: torch.device, resume: bool = False,
                 tables: tuple[str, ...] = ("metrics",)) -> None:
        self.path, self.kind, self.tables = Path(path), kind, tables
        joined = dist.is_available() and dist.is_initialized()
        self.rank, self.world = init_distributed(device)
        # The group this folder joined it leaves at close(); one its caller made stays the caller's.
        self._leave_group = self.world > 1 and not joined
        self.meta: dict[str, Any] | None = ckpt.load_meta(self.path, kind) if resume else None
        if not resume and ckpt.has_checkpoint(self.path):
            raise DancesynthError(f"{self.path} already holds a trained model; pass --resume to continue it "
                                  "or choose a new --out folder.")
        # Wall-clock seconds of training over every call of the run: what a time budget counts.
        self.trained_seconds = 0.0
        if self.meta is not None:
            with ckpt.run_file_contents(self.path / ckpt.POINTER):
                self.trained_seconds = float(self.meta.get("trained_seconds", 0.0))
        self._rows = {name: 0 for name in tables}
        self._tensorboard: Any = None
        self._purge_step: int | None = None
        if self.writer:
            self.path.mkdir(parents=True, exist_ok=True)
            ckpt.remove_stale_checkpoints(self.path)
            if not resume:
                for name in tables:
                    self.table_path(name).unlink(missing_ok=True)

    @property
    def writer(self) -> bool:
        """Whether this process writes files (rank 0)."""
        return self.rank == 0

    @property
    def resumed(self) -> bool:
        return self.meta is not None

    def table_path(self, name: str) -> Path:
        return self.path / f"{name}.csv"

    # --- distributed ------------------------------------------------------------------------------------------
    def average_gradients(self, params: Iterable[nn.Parameter]) -> None:
        """Mean gradient over processes (nothing to do in a single process)."""
        average_gradients(params, self.world)

    def agree(self, flag: bool) -> bool:
        """True in every process when it is True in rank 0 (so all processes stop at the same step)."""
        if self.world == 1:
            return flag
        t = torch.tensor([1.0 if flag else 0.0])
        dist.broadcast(t, 0)
        return bool(t.item())

    def barrier(self) -> None:
        if self.world > 1:
            dist.barrier()

    # --- checkpoints ------------------------------------------------------------------------------------------
    def save(self, model: nn.Module, meta: dict[str, Any], optimizers: dict[str, torch.optim.Optimizer],
             extra: dict[str, Any] | None = None, best: dict[str, torch.Tensor] | None = None) -> dict[str, Any]:
        """Checkpoint ``model`` with ``meta`` (JSON: ``kind`` and ``trained_seconds`` are added, ``step`` is
        expected), the optimizer states, every process's RNG states, the metrics tables' lengths, the
        trainer's ``extra`` state (tensors, numbers, strings, lists, dicts) and ``best``, the state dict of an
        earlier step that validated better (:func:`dancesynth.core.checkpoint.save_checkpoint`). Call it in
        every process; returns the metadata saved."""
        meta = {**meta, "kind": self.kind, "trained_seconds": round(self.trained_seconds, 1)}
        rng = ckpt.capture_rng_state()
        rngs: list[Any] = [rng]
        if self.world > 1:
            rngs = [None] * self.world
            dist.all_gather_object(rngs, rng)
        if self.writer:
            state = {"optimizers": {name: opt.state_dict() for name, opt in optimizers.items()}, "rng": rngs,
                     "rows": dict(self._rows), "extra": extra or {}}
            ckpt.save_checkpoint(self.path, model, meta, state, best)
        return meta

    def restore(self, model: nn.Module,
                optimizers: dict[str, torch.optim.Optimizer]) -> tuple[dict[str, Any], dict[str, Any]]:
        """Load the checkpoint being resumed into ``model`` and ``optimizers`` and restore this process's RNG
        states; truncate the metrics tables to their length at that checkpoint. Returns (meta, extra)."""
        if self.meta is None:
            raise ValueError("restore() needs a run folder opened with resume=True")
        state_dict, meta = ckpt.load_checkpoint(self.path, self.kind)
        training = ckpt.load_training_state(self.path, meta)
        if "extra" not in training:
            raise DancesynthError(f"{self.path} was saved by an older dancesynth whose training state cannot be "
                                  "resumed; start a new run with another --out folder"
                                  f"{ckpt.or_delete_cached(self.path)}.")
        with ckpt.run_file_contents(self.path / ckpt.POINTER):
            model.load_state_dict(state_dict)
            self._purge_step = int(meta.get("step", 0)) + 1
        with ckpt.run_file_contents(ckpt.checkpoint_files(self.path, meta)[1]):
            if len(training["rng"]) != self.world:
                raise DancesynthError(f"{self.path} was trained with {len(training['rng'])} processes; resume it "
                                      "with the same number so the continuation is exact.")
            if not isinstance(training["extra"], dict):
                raise TypeError("its trainer state is not a table")
            for name, opt in optimizers.items():
                opt.load_state_dict(training["optimizers"][name])
            ckpt.restore_rng_state(training["rng"][self.rank])
            rows = {name: int(training["rows"].get(name, 0)) for name in self.tables}
        self.meta, self._rows = meta, rows
        if self.writer:
            for name, count in self._rows.items():
                keep_rows(self.table_path(name), count)
        return meta, training["extra"]

    def update_meta(self, entries: dict[str, Any]) -> None:
        """Add ``entries`` (e.g. final accuracies) to the current checkpoint's metadata (rank 0 writes)."""
        if self.writer:
            self.meta = ckpt.update_meta(self.path, self.kind, entries)

    # --- the training loop ------------------------------------------------------------------------------------
    @contextlib.contextmanager
    def training(self, save: Callable[[], object], minutes: float | None, total_steps: int, step: int,
                 desc: str) -> Iterator[TrainingSession]:
        """Run a trainer's loop under the protocol of the module docstring: Ctrl-C / SIGTERM deferred to the
        end of a step, then ``save()`` (the trainer's checkpoint) and :class:`KeyboardInterrupt`; ``minutes``
        of training in all (None: no limit); progress over ``total_steps`` optimiser steps in all, ``step`` of
        them done before this call."""
        with deferred_interrupts() as stop:
            session = TrainingSession(self, stop, minutes, total_steps, step, desc)
            try:
                yield session
            finally:
                session.progress.close()
            # Every process saves, or none: a signal that reached only some of them counts as rank 0 sees it.
            interrupted = self.agree(stop.requested)
        if interrupted:
            save()
            raise KeyboardInterrupt

    # --- logs -------------------------------------------------------------------------------------------------
    def log(self, table: str, row: dict[str, Any]) -> None:
        """Append ``row`` (it has a ``step`` entry) to ``TABLE.csv`` and its numbers to TensorBoard. Rank 0 only."""
        if not self.writer:
            return
        append_row(self.table_path(table), row)
        self._rows[table] += 1
        board = self._board()
        if board is not None:
            for key, value in row.items():
                if key not in ("step", "epoch") and isinstance(value, (int, float)):
                    board.add_scalar(f"{table}/{key}", value, int(row["step"]))

    def _board(self) -> Any:
        """The TensorBoard writer, opened on first use; None when the optional package is missing."""
        if self._tensorboard is None:
            try:
                from torch.utils.tensorboard import SummaryWriter
            except ImportError:  # tensorboard is optional: the CSV tables and their plot always exist
                self._tensorboard = False
                return None
            # A resumed run drops the events logged after its checkpoint, as it drops those CSV rows.
            self._tensorboard = SummaryWriter(str(self.path / "tensorboard"), purge_step=self._purge_step)
        return self._tensorboard or None

    def plot(self, name: str) -> None:
        """Draw every table's curves against ``step`` into ``NAME`` (e.g. ``loss.png``). Rank 0 only."""
        if self.writer:
            plot_metrics([self.table_path(t) for t in self.tables], self.path / name)

    def close(self) -> None:
        """End the run: TensorBoard's files closed, and every process leaves the group it joined, together (a
        process tearing gloo down while another still used it aborted with SIGABRT)."""
        if self._tensorboard:
            self._tensorboard.close()
        self._tensorboard = None
        if self._leave_group:
            dist.barrier()
            dist.destroy_process_group()
            self._leave_group = False


class TrainingSession:
    """One call of a trainer's loop, made by :meth:`RunFolder.training`: the budget, the stop request and the
    progress counter. :attr:`stopped` is True once the loop must end (from the start when the budget is spent)."""

    def __init__(self, run: RunFolder, stop: StopRequest, minutes: float | None, total_steps: int, step: int,
                 desc: str) -> None:
        self._run, self._stop = run, stop
        self._budget_s = math.inf if minutes is None else 60.0 * minutes
        self._trained_before = run.trained_seconds
        self._start = time.monotonic()
        self.stopped = run.agree(self._trained_before >= self._budget_s)
        # Under a budget progress counts its seconds, so "left" is the budget's; otherwise steps.
        self._seconds = minutes is not None
        if self._seconds:
            total = round(self._budget_s)
            initial = min(total, round(self._trained_before))
            self.progress: Progress = track(total=total, initial=initial, desc=desc, unit="s", disable=not run.writer)
        else:
            self.progress = track(total=total_steps, initial=step, desc=desc, unit="step", disable=not run.writer)

    def step_done(self, step: int, **shown: Any) -> bool:
        """Count an optimiser step (``step``: the run's steps so far) and show ``shown`` (e.g. losses); True when
        the loop must end now: the budget is spent or a stop was asked for (in every process alike)."""
        self._run.trained_seconds = self._trained_before + time.monotonic() - self._start
        bar = self.progress
        bar.set_postfix(step=step, **shown)
        bar.update(min(bar.total or 0, int(self._run.trained_seconds)) - bar.n if self._seconds else 1)
        self.stopped = self._run.agree(self._stop.requested or self._run.trained_seconds >= self._budget_s)
        return self.stopped
