import json
import tomllib

import numpy as np
import soundfile
import torch

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)

from apps.cli import main  # noqa: E402
from dancesynth.core.skeleton import PoseSequence  # noqa: E402
from stage1_pose.music_features import num_pose_frames  # noqa: E402
from stage1_pose.registry import make_config  # noqa: E402


def test_train_pose_then_generate(tiny_stage1_dataset, tmp_path, capsys):
    run, config = tmp_path / "run", tmp_path / "lstm.toml"
    config.write_text("hidden = 16\nlayers = 1\nwindow_frames = 30\n")
    sets = ["--config", str(config), "--set", "hidden=8", "--set", "batch_size=4", "--set", "epoch_windows=0"]
    assert main(["train-pose", "--method", "lstm", "--data", str(tiny_stage1_dataset), "--out", str(run),
                 "--epochs", "1", "--preview-every", "0", "--device", "cpu", *sets]) == 0
    assert "epoch 1/1" in capsys.readouterr().err
    saved = json.loads((run / "latest.json").read_text())["config"]
    assert (saved["hidden"], saved["layers"], saved["window_frames"]) == (8, 1, 30)
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


def test_print_config_is_preset_then_file_then_set_and_reads_back(tmp_path, capsys):
    base = ["train-pose", "--method", "ren", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "run")]
    config = tmp_path / "ren.toml"
    config.write_text("gru_hidden = 32\naudio_channels = [4, 8]\nw_local = 3.0\n")
    assert main([*base, "--config", str(config), "--batch-size", "6", "--set", "w_local=2", "--print-config"]) == 0
    printed = capsys.readouterr().out
    resolved = tomllib.loads(printed)
    assert (resolved["gru_hidden"], resolved["audio_channels"], resolved["w_local"]) == (32, [4, 8], 2.0)
    assert resolved["batch_size"] == 6
    assert resolved["mlp_hidden"] == make_config("ren", "small").mlp_hidden and not (tmp_path / "run").exists()
    config.write_text(printed)
    assert main([*base, "--config", str(config), "--print-config", "json"]) == 0
    assert json.loads(capsys.readouterr().out) == resolved


def test_bad_config_file_or_setting_is_a_one_line_error(tmp_path, capsys):
    base = ["train-pose", "--method", "lstm", "--data", str(tmp_path), "--out", str(tmp_path / "r"), "--print-config"]
    config = tmp_path / "bad.toml"
    config.write_text("hidden = [\n")
    assert main([*base, "--config", str(config)]) == 1
    assert "bad.toml cannot be read" in capsys.readouterr().err
    assert main([*base, "--set", "hiden=8"]) == 1
    err = capsys.readouterr().err
    assert "no setting hiden" in err and "Traceback" not in err
