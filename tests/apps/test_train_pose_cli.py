import numpy as np
import soundfile
import torch

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)

from apps.cli import main  # noqa: E402
from stage1_pose.audio import num_pose_frames  # noqa: E402
from dancesynth.core.skeleton import PoseSequence  # noqa: E402


def test_train_pose_then_generate(tiny_stage1_dataset, tmp_path, capsys):
    run = tmp_path / "run"
    sets = ["--set", "hidden=8", "--set", "layers=1", "--set", "window_frames=30", "--set", "batch_size=4"]
    assert main(["train-pose", "--method", "lstm", "--data", str(tiny_stage1_dataset), "--out", str(run),
                 "--epochs", "1", "--preview-every", "0", "--device", "cpu", *sets]) == 0
    assert "epoch 1/1" in capsys.readouterr().out
    sr = 22050
    t = np.arange(int(3.3 * sr)) / sr
    song = (0.3 * np.sin(2 * np.pi * 220 * t) * (np.sin(2 * np.pi * 2 * t) > 0)).astype(np.float32)
    soundfile.write(tmp_path / "song.wav", song, sr)
    out, preview = tmp_path / "poses.npz", tmp_path / "preview.mp4"
    assert main(["generate", str(tmp_path / "song.wav"), "--model", str(run), "--out", str(out),
                 "--preview", str(preview), "--device", "cpu"]) == 0
    seq = PoseSequence.load(out)
    assert len(seq) == num_pose_frames(len(song), sr, 15.0) and preview.stat().st_size > 0


def test_errors_are_one_line_without_traceback(tiny_stage1_dataset, tmp_path, capsys):
    assert main(["generate", str(tmp_path / "missing.wav"), "--model", str(tmp_path / "nope"),
                 "--out", str(tmp_path / "p.npz")]) == 1
    err = capsys.readouterr().err
    assert "does not exist" in err and "Traceback" not in err
    assert main(["train-pose", "--method", "lstm", "--data", str(tiny_stage1_dataset), "--out", str(tmp_path / "r"),
                 "--set", "hidden"]) == 1
    assert "FIELD=VALUE" in capsys.readouterr().err
