"""`dancesynth check` on a tiny trained stage-1 run."""

import json
import re

import pytest
import torch

from apps.cli import main
from stage1_pose.train import TrainerConfig, train

TINY_DR = dict(d_model=16, heads=2, d_k=8, d_v=8, d_ff=32, layers=1, window=6, lstm_hidden=32, window_frames=30,
               batch_size=4, epoch_windows=0)


@pytest.fixture(scope="module")
def run(tiny_stage1_dataset, tmp_path_factory):
    before = torch.get_num_threads()
    torch.set_num_threads(1)  # tiny model: threads cost more than they save on a shared machine
    out = tmp_path_factory.mktemp("check") / "run"
    train("dance_revolution", tiny_stage1_dataset, out, overrides=TINY_DR, epochs=1,
          options=TrainerConfig(preview_every=0))
    yield out
    torch.set_num_threads(before)


def test_check_prints_measures_and_a_verdict_per_criterion_and_writes_json(run, tmp_path, capsys):
    report = tmp_path / "check.json"
    assert main(["check", str(run), "--clips", "1", "--seconds", "8", "--seeds", "0", "1", "2",
                 "--json", str(report), "--device", "cpu", "--precision", "fp32"]) == 0
    printed = capsys.readouterr().err
    # The tiny dataset's held-out songs: clip4 (test), then clip3 (val); --clips 1 checks the first.
    assert "clip4           real" in printed and "clip3" not in printed
    verdict_lines = [line for line in printed.splitlines() if line.startswith("clip4 seed ")]
    assert len(verdict_lines) == 3
    for line in verdict_lines:
        assert re.fullmatch(r"clip4 seed \d: no freeze (PASS|FAIL), beats above chance \(\+0\.10\) (PASS|FAIL), "
                            r"seeds differ \(>= 10% of a real pair\) (PASS|FAIL)", line), line
    data = json.loads(report.read_text())
    assert data["run"]["method"] == "dance_revolution"
    assert [r["dance"] for r in data["rows"]] == ["real", "seed 0", "seed 1", "seed 2"]
    assert {v["dance"] for v in data["verdicts"]} == {"seed 0", "seed 1", "seed 2"}
    # Another seed gives another dance of this stochastic model.
    assert all(r["seed_gap"]["joints"] > 0 for r in data["rows"][1:])


def test_a_folder_that_is_no_stage1_run_or_one_seed_is_a_one_line_error(tiny_stage1_dataset, run, capsys):
    assert main(["check", str(tiny_stage1_dataset)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("dancesynth check: error:") and "Traceback" not in err and len(err.splitlines()) == 1
    assert main(["check", str(run), "--seeds", "0"]) == 1
    assert "at least two different seeds" in capsys.readouterr().err
