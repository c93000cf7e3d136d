"""`dancesynth make-dataset` end to end through the CLI entry point."""

from __future__ import annotations

from apps.cli import main
from stage1_pose.data.dataset import DanceDataset


def test_make_dataset_command(tmp_path, capsys):
    out = tmp_path / "ds"
    assert main(["make-dataset", "--out", str(out), "--clips", "3", "--seconds", "5", "--workers", "1"]) == 0
    assert "3 clips of 5 s" in capsys.readouterr().out
    ds = DanceDataset(out)
    assert len(ds.clips()) == 3 and {c.split for c in ds.clips()} == {"train", "val", "test"}
    assert all(len(ds.load_poses(c)) == 75 for c in ds.clips())


def test_make_dataset_command_reports_bad_input(tmp_path, capsys):
    assert main(["make-dataset", "--out", str(tmp_path / "ds"), "--clips", "0"]) == 1
    err = capsys.readouterr().err
    assert "--clips must be at least 1" in err and "Traceback" not in err
