"""benchmarks/gpu_check.py runs: its CPU path at toy sizes gives a row of numbers for every trainer and the dance,
and without a GPU the default (CUDA) run says so in one line and succeeds."""

import importlib.util
import sys
from pathlib import Path

import pytest
import torch

from stage1_pose.registry import method_names

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "gpu_check.py"
_SPEC = importlib.util.spec_from_file_location("gpu_check", _PATH)
gpu_check = importlib.util.module_from_spec(_SPEC)
sys.modules["gpu_check"] = gpu_check  # dataclasses look their module up while the class is made
_SPEC.loader.exec_module(gpu_check)


def test_every_trainer_and_the_dance_get_a_row_of_numbers_on_the_cpu(tmp_path, capsys):
    assert gpu_check.main(["--device", "cpu", "--steps", "2", "--tiny", "--out", str(tmp_path)]) == 0
    rows = {line.split(" | ")[0].strip("| "): line.split(" | ") for line in capsys.readouterr().out.splitlines()
            if line.startswith("| ") and not line.startswith("| trainer")}
    assert sorted(rows) == sorted(["ST-GCN (ren's loss)", *method_names(), "style classifier",
                                   "appearance model paper", "appearance model medium", "dance (256-px model)"])
    for name, cells in rows.items():
        speed, difference = cells[3].split()[0], cells[5].strip(" |")
        assert float(speed) > 0 and float(difference) >= 0, (name, cells)
    # The same weights on the same device: stage 1 and the classifiers compute alike in float32.
    assert all(float(rows[name][5].strip(" |")) < 1e-4 for name in ("ST-GCN (ren's loss)", "style classifier",
                                                                     *method_names()))
    assert (tmp_path / "dance.mp4").is_file()


@pytest.mark.skipif(torch.cuda.is_available(), reason="with a GPU the default run is the whole check")
def test_without_a_gpu_the_check_says_so_in_one_line_and_succeeds(capsys):
    assert gpu_check.main([]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "no CUDA GPU" in out
