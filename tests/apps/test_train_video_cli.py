import json
import tomllib

from apps.cli import main
from stage2_video.models.pix2pixhd import PRESETS


def base_args(tmp_path):
    """A train-video command line; --print-config reads nothing from the video, so any bytes will do."""
    video = tmp_path / "person.mp4"
    video.write_bytes(b"not decoded")
    return ["train-video", str(video), "--out", str(tmp_path / "run")]


def test_print_config_is_preset_then_file_then_flags_then_set(tmp_path, capsys):
    base = [*base_args(tmp_path), "--preset", "paper"]
    config = tmp_path / "model.toml"
    config.write_text("ngf = 16\nlambda_l1 = 1.0\nbatch_size = 2\n")
    assert main([*base, "--config", str(config), "--size", "256x128", "--batch-size", "3",
                 "--set", "lambda_l1=5", "--set", "temporal=false", "--print-config"]) == 0
    resolved = tomllib.loads(capsys.readouterr().out)
    assert resolved["n_downsample"] == PRESETS["paper"].n_downsample and resolved["ngf"] == 16
    assert (resolved["width"], resolved["height"], resolved["batch_size"]) == (256, 128, 3)
    assert resolved["lambda_l1"] == 5.0 and resolved["temporal"] is False
    assert not (tmp_path / "run").exists()
    assert main([*base, "--set", "ngf=8", "--print-config", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["ngf"] == 8


def test_bad_setting_is_a_one_line_error(tmp_path, capsys):
    base = [*base_args(tmp_path), "--print-config"]
    assert main([*base, "--set", "colour=red"]) == 1
    err = capsys.readouterr().err
    assert "no setting colour" in err and "known settings:" in err and "Traceback" not in err
    assert main([*base, "--set", "width=100"]) == 1
    assert "divisible" in capsys.readouterr().err
    assert main([*base, "--set", "ngf"]) == 1
    assert "FIELD=VALUE" in capsys.readouterr().err


def test_only_the_settings_the_user_chose_reach_training(tmp_path, monkeypatch):
    # Unchosen fields stay free for training's own choices (the background condition for a travelling person).
    seen = {}

    def train_video(video, **kwargs):
        seen.update(kwargs["overrides"])
        return {"epoch": 1, "step": 1}

    monkeypatch.setattr("dancesynth.api.train_video", train_video)
    assert main([*base_args(tmp_path), "--minutes", "1", "--batch-size", "3", "--set", "prior=false"]) == 0
    assert seen == {"batch_size": 3, "prior": False}
