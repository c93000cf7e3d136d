import numpy as np

from apps.cli import main
from dancesynth.core.draw import draw_pose
from dancesynth.core.media import probe_video, write_video
from dancesynth.core.skeleton import PoseSequence


def _target(folder):
    """A 20-frame video of a drifting stick figure and its poses."""
    kp = np.ones((20, 25, 3), np.float32)
    rng = np.random.default_rng(0)
    kp[..., :2] = rng.uniform(12, 52, (25, 2)) + np.arange(20)[:, None, None] * 0.3
    seq = PoseSequence(kp, 15.0, 64, 64)
    write_video(folder / "t.mp4", [draw_pose(np.full((64, 64, 3), 80, np.uint8), k) for k in kp], 15.0)
    seq.save(folder / "t.npz")


def test_train_video_then_render_from_the_command_line(tmp_path, capsys, monkeypatch):
    import stage2_video.vgg
    monkeypatch.setattr(stage2_video.vgg, "_notice_shown", False)
    _target(tmp_path)
    run = tmp_path / "run"
    assert main(["train-video", str(tmp_path / "t.mp4"), "--out", str(run), "--poses", str(tmp_path / "t.npz"),
                 "--size", "32x32", "--epochs", "1", "--batch-size", "8", "--device", "cpu"]) == 0
    assert "VGG perceptual loss is OFF" in capsys.readouterr().err
    out, scene, skeleton = tmp_path / "dance.mp4", tmp_path / "scene.mp4", tmp_path / "skeleton.mp4"
    assert main(["render", str(tmp_path / "t.npz"), "--model", str(run), "--out", str(out), "--no-normalize",
                 "--crop"]) == 0
    info = probe_video(out)
    assert (info.width, info.height, info.num_frames) == (64, 64, 20)  # the warped prior's scale: twice the model
    # Without --crop: the target's scene, here scaled to 32 px high, and its skeleton at the same size.
    assert main(["render", str(tmp_path / "t.npz"), "--model", str(run), "--out", str(scene), "--height", "32",
                 "--skeleton-preview", str(skeleton)]) == 0
    for path in (scene, skeleton):
        info = probe_video(path)
        assert (info.width, info.height, info.num_frames) == (32, 32, 20)


def test_render_errors_are_one_line_messages(tmp_path, capsys):
    _target(tmp_path)
    code = main(["render", str(tmp_path / "t.npz"), "--model", str(tmp_path / "no_run"), "--out",
                 str(tmp_path / "x.mp4")])
    err = capsys.readouterr().err
    assert code == 1 and err.startswith("dancesynth render: error:") and "Traceback" not in err
    code = main(["train-video", str(tmp_path / "t.mp4"), "--out", str(tmp_path / "r"), "--size", "30x30",
                 "--epochs", "1"])
    assert code == 1 and "divisible" in capsys.readouterr().err
    code = main(["render", str(tmp_path / "t.npz"), "--model", str(tmp_path / "no_run"), "--out",
                 str(tmp_path / "x.mp4"), "--crop", "--height", "64"])
    assert code == 1 and "use one of them" in capsys.readouterr().err
