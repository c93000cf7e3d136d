import pytest
import torch

from dancesynth.core import device as device_module
from dancesynth.core.device import cpu_flags, cpu_has_amx, cpu_has_bf16, resolve_precision
from dancesynth.core.errors import DancesynthError

CPU, CUDA = torch.device("cpu"), torch.device("cuda")


@pytest.fixture
def cpu_bf16(monkeypatch):
    """Sets whether the CPU counts as having bfloat16 instructions, whatever this machine's CPU is."""
    def set_flag(value: bool) -> None:
        monkeypatch.setattr(device_module, "cpu_has_bf16", lambda: value)
    return set_flag


def test_auto_picks_bf16_only_on_cpus_with_bf16_instructions(cpu_bf16):
    cpu_bf16(True)
    assert resolve_precision("auto", CPU) == torch.bfloat16
    assert resolve_precision("fp32", CPU) == torch.float32
    cpu_bf16(False)
    assert resolve_precision("auto", CPU) == torch.float32
    with pytest.raises(DancesynthError, match="--precision auto or fp32"):
        resolve_precision("bf16", CPU)


def test_auto_on_cuda_is_bf16_where_supported_else_fp16(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_bf16_supported", lambda *a, **k: True)
    assert resolve_precision("auto", CUDA) == torch.bfloat16
    assert resolve_precision("fp16", CUDA) == torch.float16
    monkeypatch.setattr(torch.cuda, "is_bf16_supported", lambda *a, **k: False)
    assert resolve_precision("auto", CUDA) == torch.float16
    with pytest.raises(DancesynthError, match="fp16"):
        resolve_precision("bf16", CUDA)


def test_unknown_or_unavailable_precisions_are_user_errors(cpu_bf16):
    cpu_bf16(True)
    with pytest.raises(DancesynthError, match="CUDA"):
        resolve_precision("fp16", CPU)
    with pytest.raises(DancesynthError, match="Unknown precision"):
        resolve_precision("int8", CPU)


@pytest.fixture
def fresh_detection():
    """Forgets the cached CPU detection before and after the test, so a fake /proc/cpuinfo stays in it."""
    cpu_flags.cache_clear()
    yield
    cpu_flags.cache_clear()


def test_cpu_flags_are_read_from_cpuinfo(monkeypatch, tmp_path, fresh_detection):
    cpuinfo = tmp_path / "cpuinfo"
    monkeypatch.setattr(device_module.sys, "platform", "linux")
    real_path = device_module.Path
    monkeypatch.setattr(device_module, "Path", lambda p: cpuinfo if p == "/proc/cpuinfo" else real_path(p))
    for flags, bf16, amx in (("fpu avx2 avx512f", False, False), ("fpu avx512f avx512_bf16", True, False),
                             ("fpu amx_bf16", True, True)):
        cpuinfo.write_text(f"processor\t: 0\nflags\t\t: {flags}\n")
        cpu_flags.cache_clear()
        assert (cpu_has_bf16(), cpu_has_amx()) == (bf16, amx), flags
    monkeypatch.setattr(device_module.sys, "platform", "darwin")
    cpu_flags.cache_clear()
    assert cpu_has_bf16() is False
