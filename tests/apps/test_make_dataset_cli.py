"""`dancesynth make-dataset` end to end through the CLI entry point."""

from __future__ import annotations

from apps.cli import main
from stage1_pose.data.dataset import DanceDataset


def test_make_dataset_command(tmp_path, capsys):
    out = tmp_path / "ds"
    assert main(["make-dataset", "--out", str(out), "--clips", "3", "--seconds", "5", "--workers", "1"]) == 0
    assert "3 clips of 5 s" in capsys.readouterr().err
    ds = DanceDataset(out)
    assert len(ds.clips()) == 3 and {c.split for c in ds.clips()} == {"train", "val", "test"}
    assert all(len(ds.load_poses(c)) == 75 for c in ds.clips())


def test_make_dataset_command_reports_bad_input(tmp_path, capsys):
    assert main(["make-dataset", "--out", str(tmp_path / "ds"), "--clips", "0"]) == 1
    err = capsys.readouterr().err
    assert "--clips: must be positive" in err and "Traceback" not in err


def test_import_dance_command(tmp_path, capsys):
    import numpy as np
    import soundfile

    from dancesynth.core.skeleton import COCO17_TO_BODY25

    rng = np.random.default_rng(0)
    soundfile.write(tmp_path / "song.wav", (0.1 * rng.standard_normal(3 * 22050)).astype(np.float32), 22050)
    kp = np.ones((180, 25, 3), np.float32)
    kp[..., :2] = 500 + rng.uniform(-50, 50, (1, 25, 2)) + np.sin(np.arange(180) / 9)[:, None, None] * 30
    np.save(tmp_path / "gPO_x.npy", kp[:, list(COCO17_TO_BODY25)])
    out = tmp_path / "ds"
    assert main(["import-dance", "--out", str(out), "--aistpp", str(tmp_path / "gPO_x.npy"),
                 "--audio", str(tmp_path / "song.wav"), "--split", "test"]) == 0
    assert "added clip gPO_x (style pop, split test)" in capsys.readouterr().err
    assert len(DanceDataset(out).load_poses(DanceDataset(out).clips()[0])) == 45
    assert main(["import-dance", "--out", str(out), "--openpose", str(tmp_path), "--audio",
                 str(tmp_path / "song.wav")]) == 1
    assert "--openpose needs --style, --fps, --width, --height" in capsys.readouterr().err
