"""Choosing the torch device (`--device auto|cpu|cuda`) and the numeric precision (`--precision auto|fp32|bf16|fp16`)
from the hardware found at run time."""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import torch

from dancesynth.core.errors import DancesynthError

# `--precision` names -> the dtype that autocast (and OpenVINO's inference hint) computes in.
PRECISIONS = {"fp32": torch.float32, "bf16": torch.bfloat16, "fp16": torch.float16}
# CPU flags (Linux /proc/cpuinfo) of the instructions that make bfloat16 matrix products fast.
BF16_CPU_FLAGS = frozenset({"amx_bf16", "avx512_bf16"})


def resolve_device(name: str = "auto") -> torch.device:
    """``auto`` -> CUDA when available, else CPU; ``cuda`` without a GPU is a user error."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise DancesynthError("--device cuda was asked for but no CUDA GPU is visible; use --device cpu or auto.")
    if name != "cpu" and not name.startswith("cuda"):
        raise DancesynthError(f"Unknown device {name!r}; use auto, cpu or cuda.")
    return torch.device(name)


@functools.cache
def cpu_flags() -> frozenset[str]:
    """This CPU's feature flags (read once from Linux's /proc/cpuinfo; empty on other systems)."""
    if not sys.platform.startswith("linux"):
        return frozenset()
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return frozenset()
    for line in text.splitlines():
        if line.startswith("flags"):
            return frozenset(line.partition(":")[2].split())
    return frozenset()


def cpu_has_bf16() -> bool:
    """Whether this CPU has AMX-BF16 or AVX-512-BF16 instructions."""
    return not BF16_CPU_FLAGS.isdisjoint(cpu_flags())


def cpu_has_amx() -> bool:
    """Whether this CPU has AMX bfloat16 tile instructions (Xeon Sapphire Rapids and later)."""
    return "amx_bf16" in cpu_flags()


def resolve_precision(name: str, device: torch.device) -> torch.dtype:
    """The dtype to compute in on ``device`` for ``--precision name``.

    ``auto``: bfloat16 on CPUs with AMX or AVX-512-BF16 and on GPUs that support it, float16 on other GPUs,
    float32 elsewhere. Asking for a precision the hardware lacks is a user error.
    """
    if name == "auto":
        if device.type == "cuda":
            return torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
        return torch.bfloat16 if device.type == "cpu" and cpu_has_bf16() else torch.float32
    if name not in PRECISIONS:
        raise DancesynthError(f"Unknown precision {name!r}; use auto, fp32, bf16 or fp16 (CUDA only).")
    if name == "fp16" and device.type != "cuda":
        raise DancesynthError("--precision fp16 needs a CUDA GPU; use --precision auto, fp32 or bf16 on this device.")
    if name == "bf16" and device.type == "cuda" and not torch.cuda.is_bf16_supported():
        raise DancesynthError("--precision bf16 was asked for but this GPU has no bfloat16 support; use --precision "
                              "auto or fp16.")
    if name == "bf16" and device.type == "cpu" and not cpu_has_bf16():
        raise DancesynthError("--precision bf16 was asked for but this CPU has no bfloat16 instructions (AMX or "
                              "AVX-512-BF16); use --precision auto or fp32.")
    return PRECISIONS[name]


def precision_name(dtype: torch.dtype) -> str:
    """The `--precision` name of ``dtype`` (``fp32``, ``bf16`` or ``fp16``)."""
    return next(name for name, value in PRECISIONS.items() if value == dtype)
