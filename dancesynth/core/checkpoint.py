"""Run folders: model checkpoints (safetensors + JSON) and the training state that makes resume exact.

A checkpoint ``TAG`` in a run folder is three files, each written atomically:

* ``TAG.safetensors`` - the model's state dict (weights and buffers), nothing executable;
* ``TAG.json`` - metadata: at least ``kind`` (``"stage1"``, ``"stage2"``, ``"stgcn"`` ...) plus whatever the
  trainer needs to rebuild the model (method, config, epoch, step, curriculum state, feature stats, fps, canvas);
* ``TAG.training.pt`` - optional: optimizer states, RNG states, data position. Plain tensors / dicts / lists
  only, read back with ``torch.load(weights_only=True)``.

The JSON is written last and carries a ``save_id`` that the other two files repeat, so a crash between the
renames is detected instead of silently pairing new weights with old metadata.
"""

from __future__ import annotations

import json
import os
import random
import secrets
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import load_file, save_file
from torch import nn

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path

# What each kind of run is and how it is made: used to tell a user what to pass instead.
KIND_DESCRIPTIONS: dict[str, str] = {
    "stage1": "a pose model trained with `dancesynth train-pose`",
    "stage2": "an appearance model trained with `dancesynth train-video`",
    "stgcn": "an ST-GCN pose classifier trained with `dancesynth train-stgcn`",
    "style_classifier": "a style classifier trained with `dancesynth train-style-classifier`",
}


def _describe(kind: str) -> str:
    return KIND_DESCRIPTIONS.get(kind, f"a {kind!r} run")


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


def save_checkpoint(run_dir: str | os.PathLike, model: nn.Module, meta: dict[str, Any],
                    training_state: dict[str, Any] | None = None, tag: str = "latest") -> None:
    """Write ``run_dir/TAG.safetensors``, ``TAG.json`` and (if given) ``TAG.training.pt``.

    ``meta`` must be JSON-serialisable and contain ``kind``. ``training_state`` may hold tensors, numbers,
    strings, lists, tuples and dicts (e.g. ``optimizer.state_dict()``, :func:`capture_rng_state`). The run
    folder is created if needed.
    """
    if "kind" not in meta:
        raise ValueError("checkpoint meta needs a 'kind' entry (e.g. 'stage1')")
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    save_id = secrets.token_hex(8)
    text = json.dumps({**meta, "save_id": save_id}, indent=2, sort_keys=True)
    if training_state is not None:
        with atomic_path(run_dir / f"{tag}.training.pt") as tmp:
            torch.save({"save_id": save_id, "state": training_state}, tmp)
    with atomic_path(run_dir / f"{tag}.safetensors") as tmp:
        save_file(_plain_state_dict(model), str(tmp), metadata={"save_id": save_id, "kind": str(meta["kind"])})
    with atomic_path(run_dir / f"{tag}.json") as tmp:
        tmp.write_text(text)


def load_meta(run_dir: str | os.PathLike, expected_kind: str, tag: str = "latest") -> dict[str, Any]:
    """The JSON metadata of checkpoint ``tag``, after checking the folder is a run of ``expected_kind``."""
    run_dir = Path(run_dir)
    what = _describe(expected_kind)
    if not run_dir.is_dir():
        raise DancesynthError(f"Run folder {run_dir} does not exist; pass the --out folder of {what}.")
    path = run_dir / f"{tag}.json"
    if not path.is_file():
        raise DancesynthError(f"{run_dir} holds no {tag!r} checkpoint ({path.name} is missing), so it is not a "
                              f"finished dancesynth run; pass the --out folder of {what}.")
    try:
        meta = json.loads(path.read_text())
        kind = meta["kind"]
    except (json.JSONDecodeError, KeyError, TypeError, UnicodeDecodeError) as e:
        raise DancesynthError(f"{path} is not dancesynth checkpoint metadata; pass the --out folder of {what}.") from e
    if kind != expected_kind:
        raise DancesynthError(f"{run_dir} is {_describe(kind)}, but {what} is needed here; pass such a run folder instead.")
    return meta


def load_checkpoint(run_dir: str | os.PathLike, expected_kind: str,
                    tag: str = "latest") -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """``(state_dict, meta)`` of checkpoint ``tag``; tensors on CPU.

    Raises :class:`DancesynthError` when the folder is missing, is not a dancesynth run, is a run of another
    kind (e.g. an appearance model given where a pose model is expected) or was interrupted while saving.
    """
    meta = load_meta(run_dir, expected_kind, tag)
    path = Path(run_dir) / f"{tag}.safetensors"
    if not path.is_file():
        raise DancesynthError(f"{path} is missing; the run folder is incomplete, retrain or copy the whole folder.")
    try:
        state = load_file(str(path))
        with safe_open(str(path), framework="pt") as f:
            file_meta = f.metadata() or {}
    except (SafetensorError, OSError) as e:
        raise DancesynthError(f"{path} is not a readable safetensors file ({e}); retrain or copy the run again.") from e
    if file_meta.get("save_id") != meta.get("save_id"):
        raise DancesynthError(f"{path} does not belong to {path.with_suffix('.json').name} (the run was stopped "
                              "while saving); resume or retrain the run.")
    return state, meta


def load_training_state(run_dir: str | os.PathLike, tag: str = "latest") -> dict[str, Any]:
    """The ``training_state`` saved with checkpoint ``tag`` (optimizers, RNG, data position)."""
    run_dir = Path(run_dir)
    path = run_dir / f"{tag}.training.pt"
    if not path.is_file():
        raise DancesynthError(f"{run_dir} has no training state ({path.name}); it cannot be resumed, "
                              "start a new run with another --out folder.")
    try:
        saved = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, OSError, EOFError) as e:
        raise DancesynthError(f"{path} is unreadable ({e}); start a new run with another --out folder.") from e
    meta_path = run_dir / f"{tag}.json"
    if meta_path.is_file() and json.loads(meta_path.read_text()).get("save_id") != saved.get("save_id"):
        raise DancesynthError(f"{path} does not belong to {meta_path.name} (the run was stopped while saving); "
                              "start a new run with another --out folder.")
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
