"""Checkpoint files: model weights (safetensors) + JSON metadata + the training state that makes resume exact.

A run folder holds one current checkpoint, reached through the pointer file ``latest.json``::

    RUN_DIR/latest.json                      metadata: ``kind`` ("stage1", "stage2", "stgcn" ...), what the
                                             trainer needs to rebuild the model, and ``checkpoint``: the folder
    RUN_DIR/ckpt-<step>-<id>/model.safetensors   the state dict (weights and buffers), nothing executable
    RUN_DIR/ckpt-<step>-<id>/training.pt         optional: optimizer and RNG states, data position; plain
                                                 tensors / dicts / lists, read with ``torch.load(weights_only=True)``
    RUN_DIR/ckpt-<step>-<id>/best.safetensors    optional: the weights of an earlier step that validated best,
                                                 which a trainer keeping the best checkpoint renders with

A save writes a new checkpoint folder completely beside the current one (under a unique temporary name,
renamed when complete), then switches to it with one atomic rename of ``latest.json``, and only then deletes
the previous folder. A process killed at any instant therefore leaves the previous or the new checkpoint
readable, never a mix; leftovers of an interrupted save are deleted by the next save or when a trainer
opens the folder. A ``save_id`` in the JSON is repeated in both files, so a stray file is detected.

Runs written before checkpoints got folders (``latest.safetensors`` / ``latest.training.pt`` beside
``latest.json``) are still loaded; their next save moves them to the folder layout.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import pickle
import random
import re
import secrets
import shutil
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import load_file, save_file
from torch import nn

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import PART_MARKER, atomic_path

POINTER = "latest.json"
WEIGHTS = "model.safetensors"
BEST_WEIGHTS = "best.safetensors"
TRAINING = "training.pt"
LEGACY_WEIGHTS, LEGACY_TRAINING = "latest.safetensors", "latest.training.pt"
_CHECKPOINT_DIR = re.compile(r"^ckpt-\d+-[0-9a-f]+$")

# What each kind of run is and how it is made: used to tell a user what to pass instead.
KIND_DESCRIPTIONS: dict[str, str] = {
    "stage1": "a pose model trained with `dancesynth train-pose`",
    "stage2": "an appearance model trained with `dancesynth train-video`",
    "stgcn": "an ST-GCN pose classifier trained with `dancesynth train-stgcn`",
    "style_classifier": "a style classifier trained with `dancesynth train-style-classifier`",
}


# What a hand-edited or damaged run file makes fail while a model or a training is rebuilt from it: a missing
# entry, a value of the wrong type or range, weights that do not fit the config (load_state_dict's RuntimeError).
_CONTENT_ERRORS = (KeyError, TypeError, ValueError, IndexError, AttributeError, ZeroDivisionError, RuntimeError)


def _describe(kind: str) -> str:
    return KIND_DESCRIPTIONS.get(kind, f"a {kind!r} run")


def or_delete_cached(run_dir: str | os.PathLike) -> str:
    """The end of a sentence telling what to do with a damaged run folder that is a cache entry of
    `dance --target` (stage2_video.model_cache), which the user never gave as an --out folder."""
    return f", or, if {run_dir} is a model that `dance --target` cached, delete that folder so it is trained again"


@contextlib.contextmanager
def run_file_contents(path: str | os.PathLike) -> Iterator[None]:
    """Turn an error raised while the contents of ``path`` (a run's ``latest.json`` or training state) are put
    to use into one :class:`DancesynthError` naming the file; wrap only code that reads that file's values."""
    try:
        yield
    except _CONTENT_ERRORS as e:
        reason = " ".join(str(e).split())[:160] or type(e).__name__
        raise DancesynthError(f"{path} does not fit the model it belongs to ({reason}); it was edited or damaged, "
                              "so retrain or copy the whole run folder again.") from e


def _plain_state_dict(model: nn.Module) -> dict[str, torch.Tensor]:
    """CPU, contiguous tensors with no shared storage (safetensors refuses aliases, e.g. tied weights)."""
    out: dict[str, torch.Tensor] = {}
    seen: set[int] = set()
    for name, tensor in model.state_dict().items():
        t = tensor.detach().cpu().contiguous()
        ptr = t.untyped_storage().data_ptr()
        if ptr in seen and t.numel() > 0:
            t = t.clone()
        seen.add(ptr)
        out[name] = t
    return out


def has_checkpoint(run_dir: str | os.PathLike) -> bool:
    """Whether ``run_dir`` holds a checkpoint (its pointer file exists)."""
    return (Path(run_dir) / POINTER).is_file()


def save_checkpoint(run_dir: str | os.PathLike, model: nn.Module | dict[str, torch.Tensor], meta: dict[str, Any],
                    training_state: dict[str, Any] | None = None, best: dict[str, torch.Tensor] | None = None) -> None:
    """Make (model or state dict, ``meta``, ``training_state``, ``best``) the current checkpoint of ``run_dir``,
    atomically.

    ``meta`` must be JSON-serialisable and contain ``kind``; an integer ``step`` entry names the checkpoint
    folder. ``training_state`` may hold tensors, numbers, strings, lists, tuples and dicts (e.g.
    ``optimizer.state_dict()``, :func:`capture_rng_state`). ``best``: the state dict of an earlier step that
    validated better than the model's, read back with ``load_checkpoint(..., best=True)``. The run folder is
    created if needed.
    """
    if "kind" not in meta:
        raise ValueError("checkpoint meta needs a 'kind' entry (e.g. 'stage1')")
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    save_id = secrets.token_hex(8)
    name = f"ckpt-{int(meta.get('step', 0)):08d}-{save_id}"
    text = json.dumps({**meta, "checkpoint": name, "save_id": save_id}, indent=2, sort_keys=True)
    with atomic_path(run_dir / name, folder=True) as tmp:
        tmp.mkdir()
        tensors = _plain_state_dict(model) if isinstance(model, nn.Module) else model
        _save_weights(tensors, tmp / WEIGHTS, {"save_id": save_id, "kind": str(meta["kind"])})
        if best is not None:
            _save_weights(best, tmp / BEST_WEIGHTS, {"save_id": save_id, "kind": str(meta["kind"])})
        if training_state is not None:
            # Serialised in memory and written by Python: torch reports a failed write (a full or read-only
            # disk) as a RuntimeError without the cause, Python's OSError names it.
            buffer = io.BytesIO()
            torch.save({"save_id": save_id, "state": training_state}, buffer)
            (tmp / TRAINING).write_bytes(buffer.getbuffer())
    with atomic_path(run_dir / POINTER) as tmp:
        tmp.write_text(text)
    remove_stale_checkpoints(run_dir)


def export_checkpoint(run_dir: str | os.PathLike, dest: str | os.PathLike, expected_kind: str,
                      drop: tuple[str, ...] = ()) -> Path:
    """Copy the current checkpoint of ``run_dir`` to the new run folder ``dest`` with its weights and metadata
    only (no optimizer or RNG state, nothing to resume): what a release ships. ``drop`` names metadata entries
    left out (e.g. a local dataset path). The folder appears complete or not at all."""
    state, meta = load_checkpoint(run_dir, expected_kind)
    meta = {k: v for k, v in meta.items() if k not in {"checkpoint", "save_id", *drop}}
    with atomic_path(Path(dest), folder=True) as tmp:
        save_checkpoint(tmp, {name: t.contiguous() for name, t in state.items()}, meta)
    return Path(dest)


def _save_weights(tensors: dict[str, torch.Tensor], path: Path, metadata: dict[str, str]) -> None:
    """safetensors' ``save_file``, its I/O failures (e.g. a full disk) raised as the OSError they are."""
    try:
        save_file(tensors, str(path), metadata=metadata)
    except SafetensorError as e:
        code = re.search(r"os error (\d+)", str(e))
        if code is None:
            raise
        raise OSError(int(code.group(1)), os.strerror(int(code.group(1))), str(path)) from e


def update_meta(run_dir: str | os.PathLike, expected_kind: str, entries: dict[str, Any]) -> dict[str, Any]:
    """Add ``entries`` (e.g. a final test accuracy) to the current checkpoint's metadata; returns the new meta."""
    meta = {**load_meta(run_dir, expected_kind), **entries}
    with atomic_path(Path(run_dir) / POINTER) as tmp:
        tmp.write_text(json.dumps(meta, indent=2, sort_keys=True))
    return meta


def remove_stale_checkpoints(run_dir: str | os.PathLike) -> None:
    """Delete what interrupted or superseded saves left: checkpoint folders other than the current one, their
    temporary folders and temporary pointer files (and the files of the pre-folder layout once moved on)."""
    run_dir = Path(run_dir)
    current = None
    if has_checkpoint(run_dir):
        try:
            current = json.loads((run_dir / POINTER).read_text()).get("checkpoint")
        except (json.JSONDecodeError, UnicodeDecodeError, AttributeError):
            return  # not our pointer: touch nothing
        if current is not None and not (isinstance(current, str) and _CHECKPOINT_DIR.match(current)
                                         and (run_dir / current).is_dir()):
            return  # an edited or damaged pointer: the checkpoint it meant may be any folder, keep them all
    stem = Path(POINTER).stem
    for entry in run_dir.iterdir():
        name = entry.name
        stale_dir = _CHECKPOINT_DIR.match(name) and name != current
        temporary = PART_MARKER in name and (name.startswith(".ckpt-") or name.startswith(f".{stem}."))
        legacy = current is not None and name in (LEGACY_WEIGHTS, LEGACY_TRAINING)
        if stale_dir or temporary or legacy:
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


def checkpoint_files(run_dir: Path, meta: dict[str, Any]) -> tuple[Path, Path]:
    """(weights, training state) paths of the checkpoint ``meta`` describes."""
    if "checkpoint" in meta:
        name = meta["checkpoint"]
        if not isinstance(name, str) or not _CHECKPOINT_DIR.match(name):
            raise DancesynthError(f"{run_dir / POINTER} names {name!r} as its checkpoint, which is not a checkpoint "
                                  "folder of this run; it was edited or damaged, so retrain or copy the run again.")
        folder = run_dir / name
        return folder / WEIGHTS, folder / TRAINING
    return run_dir / LEGACY_WEIGHTS, run_dir / LEGACY_TRAINING


def load_meta(run_dir: str | os.PathLike, expected_kind: str) -> dict[str, Any]:
    """The JSON metadata of the current checkpoint, after checking the folder is a run of ``expected_kind``."""
    run_dir = Path(run_dir)
    what = _describe(expected_kind)
    if not run_dir.is_dir():
        raise DancesynthError(f"Run folder {run_dir} does not exist; pass the --out folder of {what}.")
    path = run_dir / POINTER
    if not path.is_file():
        raise DancesynthError(f"{run_dir} holds no checkpoint ({path.name} is missing), so it is not a "
                              f"finished dancesynth run; pass the --out folder of {what}.")
    try:
        meta = json.loads(path.read_text())
        kind = meta["kind"]
        if not isinstance(kind, str):
            raise TypeError(f"kind {kind!r} is not a name")
    except (json.JSONDecodeError, KeyError, TypeError, UnicodeDecodeError) as e:
        raise DancesynthError(f"{path} is not dancesynth checkpoint metadata; pass the --out folder of {what}"
                              f"{or_delete_cached(run_dir)}.") from e
    if kind != expected_kind:
        raise DancesynthError(f"{run_dir} is {_describe(kind)}, but {what} is needed here; "
                              "pass such a run folder instead.")
    return meta


def load_checkpoint(run_dir: str | os.PathLike, expected_kind: str,
                    best: bool = False) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """``(state_dict, meta)`` of the current checkpoint; tensors on CPU. With ``best``, the weights of the step that
    validated best where the checkpoint holds them apart (``save_checkpoint(..., best=)``), else its own.

    Raises :class:`DancesynthError` when the folder is missing, is not a dancesynth run, is a run of another
    kind (e.g. an appearance model given where a pose model is expected) or is incomplete. A checkpoint
    replaced by a training that is still running while this reads it is followed to the new one.
    """
    run_dir = Path(run_dir)
    while True:
        meta = load_meta(run_dir, expected_kind)
        path = checkpoint_files(run_dir, meta)[0]
        if best and path.with_name(BEST_WEIGHTS).is_file() and path.name == WEIGHTS:
            path = path.with_name(BEST_WEIGHTS)
        try:
            state = load_file(str(path))
            with safe_open(str(path), framework="pt") as f:
                file_meta = f.metadata() or {}
            break
        except FileNotFoundError as e:
            if load_meta(run_dir, expected_kind).get("save_id") == meta.get("save_id"):
                raise DancesynthError(f"{path} is missing; the run folder is incomplete, retrain or copy the "
                                      "whole folder.") from e
        except (SafetensorError, OSError) as e:
            raise DancesynthError(f"{path} is not a readable safetensors file ({e}); retrain or copy the run "
                                  "again.") from e
    if file_meta.get("save_id") != meta.get("save_id"):
        raise DancesynthError(f"{path} does not belong to {run_dir / POINTER} (the run was stopped while saving); "
                              "resume or retrain the run.")
    return state, meta


def load_training_state(run_dir: str | os.PathLike, meta: dict[str, Any]) -> dict[str, Any]:
    """The ``training_state`` saved with the checkpoint whose metadata is ``meta`` (optimizers, RNG, position)."""
    path = checkpoint_files(Path(run_dir), meta)[1]
    if not path.is_file():
        raise DancesynthError(f"{run_dir} has no training state ({path.name}); it cannot be resumed, "
                              f"start a new run with another --out folder{or_delete_cached(run_dir)}.")
    try:
        with warnings.catch_warnings():  # a foreign pickle's protocol warning would add lines to the one error
            warnings.filterwarnings("ignore", message="Detected pickle protocol")
            saved = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, OSError, EOFError, ValueError, pickle.UnpicklingError) as e:
        # weights_only refuses pickled code as UnpicklingError; random bytes raise any of the others.
        raise DancesynthError(f"{path} is not a training state this program wrote ({type(e).__name__}); "
                              f"start a new run with another --out folder{or_delete_cached(run_dir)}.") from e
    if not isinstance(saved, dict) or not isinstance(saved.get("state"), dict):
        raise DancesynthError(f"{path} is not a training state this program wrote (no state table); "
                              f"start a new run with another --out folder{or_delete_cached(run_dir)}.")
    if saved.get("save_id") != meta.get("save_id"):
        raise DancesynthError(f"{path} does not belong to {Path(run_dir) / POINTER} (the run was stopped while "
                              f"saving); start a new run with another --out folder{or_delete_cached(run_dir)}.")
    return saved["state"]


def capture_rng_state() -> dict[str, Any]:
    """The python, numpy and torch (CPU and CUDA) random states as plain tensors/lists for the training state."""
    _, mt, pos, has_gauss, gauss = np.random.get_state()
    _, py_key, py_gauss = random.getstate()
    state: dict[str, Any] = {
        "python": {"key": list(py_key), "gauss": py_gauss},
        "numpy": {"key": torch.from_numpy(mt.astype(np.int64)), "pos": int(pos), "has_gauss": int(has_gauss),
                  "gauss": float(gauss)},
        "torch": torch.get_rng_state(),
    }
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def restore_rng_state(state: dict[str, Any]) -> None:
    """Inverse of :func:`capture_rng_state`."""
    random.setstate((3, tuple(int(v) for v in state["python"]["key"]), state["python"]["gauss"]))
    n = state["numpy"]
    np.random.set_state(("MT19937", n["key"].numpy().astype(np.uint32), n["pos"], n["has_gauss"], n["gauss"]))
    torch.set_rng_state(state["torch"])
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])
