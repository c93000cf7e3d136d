"""Choosing the torch device from a `--device auto|cpu|cuda` option."""

from __future__ import annotations

import torch

from dancesynth.core.errors import DancesynthError


def resolve_device(name: str = "auto") -> torch.device:
    """``auto`` -> CUDA when available, else CPU; ``cuda`` without a GPU is a user error."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise DancesynthError("--device cuda was asked for but no CUDA GPU is visible; use --device cpu or auto.")
    if name != "cpu" and not name.startswith("cuda"):
        raise DancesynthError(f"Unknown device {name!r}; use auto, cpu or cuda.")
    return torch.device(name)
