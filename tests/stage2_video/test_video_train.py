import csv

import numpy as np
import pytest
import torch

from dancesynth.core import device as device_module
from dancesynth.core.checkpoint import load_checkpoint
from dancesynth.core.draw import draw_pose
from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import write_video
from dancesynth.core.skeleton import PoseSequence
from stage2_video import train as train_module
from stage2_video.quality import box_scores
from stage2_video.render import load_appearance_model
from stage2_video.train import TrainOptions, VideoTrainer, train_video, video_trainer
from stage2_video.training_data import FramePairs


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("precision", ["fp32", "bf16"])
def test_tiny_model_learns_to_reproduce_frames(tiny_target, tiny_config, tmp_path, monkeypatch, precision):
    # bf16 autocast runs on any CPU (slowly without AMX/AVX-512-BF16), so the test does not depend on this one's.
    monkeypatch.setattr(device_module, "cpu_has_bf16", lambda: True)
    video, poses = tiny_target
    meta = train_video(video, tmp_path, "small", TrainOptions(epochs=6, val_frames=4, sample_every=1000,
                                                              checkpoint_every=1000),
                       poses=poses, device="cpu", precision=precision,
                       # pix2pixHD alone, with its adversarial losses: a warped prior would hand it the frames
                       overrides={**tiny_config, "lr": 2e-3, "background": False, "blend": False, "prior": False,
                                  "lambda_gan": 1.0, "lambda_feat": 10.0})
    rows = _rows(tmp_path / "losses.csv")
    l1 = np.array([float(r["g_l1"]) for r in rows])
    assert len(rows) == meta["step"] == 6 * 5
    assert l1[-5:].mean() < 0.6 * l1[:5].mean()
    assert all(float(r["d"]) > 0 for r in rows)  # the discriminators trained alongside
    assert meta["kind"] == "stage2" and meta["target_stats"] is not None
    for name in ("latest.json", "poses.npz", "losses.png", "validation.csv"):
        assert (tmp_path / name).is_file(), name
    weights, saved = load_checkpoint(tmp_path, "stage2")
    assert saved["step"] == meta["step"] and saved["precision"] == precision
    assert {w.dtype for w in weights.values() if w.is_floating_point()} == {torch.float32}
    assert [r["step"] for r in _rows(tmp_path / "validation.csv")] == [str(meta["step"])]
    assert list((tmp_path / "samples").glob("step_*.png"))


def test_resume_is_exact(tiny_target, tiny_config, tmp_path):
    video, poses = tiny_target
    straight, split = tmp_path / "straight", tmp_path / "split"
    opts = dict(epochs=2, val_frames=2, sample_every=1000, checkpoint_every=1000)
    train_video(video, straight, "small", TrainOptions(**opts), poses=poses, device="cpu", overrides=tiny_config)
    train_video(video, split, "small", TrainOptions(**opts, max_steps=3), poses=poses, device="cpu",
                overrides=tiny_config)
    with pytest.raises(DancesynthError, match="--resume"):
        train_video(video, split, "small", TrainOptions(**opts), poses=poses, device="cpu", overrides=tiny_config)
    meta = train_video(video, split, "small", TrainOptions(**opts), resume=True, poses=poses, device="cpu")
    assert meta["step"] == 10
    a, b = load_checkpoint(straight, "stage2")[0], load_checkpoint(split, "stage2")[0]
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k
    assert [r["step"] for r in _rows(split / "losses.csv")] == [str(s) for s in range(1, 11)]
    # step 0: the warped prior alone, the first candidate for the best checkpoint
    assert [r["step"] for r in _rows(split / "validation.csv")] == ["0", "3", "10"]
    a, b = load_checkpoint(straight, "stage2", best=True), load_checkpoint(split, "stage2", best=True)
    assert a[1]["best"] == b[1]["best"]
    for k in a[0]:
        assert torch.equal(a[0][k], b[0][k]), k


def _scripted_selection(monkeypatch, scores):
    """Make the trainer's validation report ``scores`` (by step) as its selection frames' SSIM."""
    validate = VideoTrainer.validate

    def scripted(self):
        return {**validate(self), "select_ssim": scores[self.step]}

    monkeypatch.setattr(VideoTrainer, "validate", scripted)


def test_the_model_renders_with_the_checkpoint_that_scored_best_on_the_selection_frames(
        tiny_target, tiny_config, tmp_path, monkeypatch):
    video, poses = tiny_target
    opts = dict(val_frames=2, sample_every=1000, checkpoint_every=3)
    reference, run = tmp_path / "reference", tmp_path / "run"
    train_video(video, reference, "small", TrainOptions(epochs=2, max_steps=3, **opts), poses=poses, device="cpu",
                overrides=tiny_config)
    _scripted_selection(monkeypatch, {0: 0.5, 3: 0.9, 6: 0.7, 9: 0.8, 10: 0.6})
    meta = train_video(video, run, "small", TrainOptions(epochs=2, **opts), poses=poses, device="cpu",
                       overrides=tiny_config)
    assert meta["step"] == 10 and meta["best"]["step"] == 3 and meta["best"]["select_ssim"] == 0.9
    kept = load_checkpoint(reference, "stage2")[0]
    model = load_appearance_model(run, "cpu", optimize=False, precision="fp32")
    rendered = model.generator.state_dict()
    for k, v in rendered.items():
        assert torch.equal(v, kept[f"generator.inner.{k}"]), k
    # the latest weights still resume the run
    assert not torch.equal(load_checkpoint(run, "stage2")[0]["generator.inner.head.1.weight"],
                           kept["generator.inner.head.1.weight"])


def test_training_that_scores_below_the_warp_alone_renders_the_warp(tiny_target, tiny_config, tmp_path, monkeypatch):
    video, poses = tiny_target
    _scripted_selection(monkeypatch, {0: 0.9, 3: 0.5, 5: 0.4})
    run = tmp_path / "run"
    meta = train_video(video, run, "small", TrainOptions(epochs=1, val_frames=2, sample_every=1000,
                                                         checkpoint_every=3),
                       poses=poses, device="cpu", overrides=tiny_config)
    assert meta["step"] == 5 and meta["best"]["step"] == 0
    assert load_appearance_model(run, "cpu").generator is None


def test_checkpoints_are_scored_as_they_render_in_the_persons_box(tiny_target, tiny_config, tmp_path):
    video, poses = tiny_target
    trainer = video_trainer(video, tmp_path, "small", TrainOptions(minutes=0, val_frames=3), poses=poses,
                            device="cpu", overrides=tiny_config)
    target, frames = trainer.target, trainer.select_range
    pairs, renderer = FramePairs(target, frames), target.renderer()
    picks = [t for t in frames if target.usable[t]][:3]
    # before training the model renders the warp at the bank's size: that, in the person's box, is the score
    expected = np.mean([box_scores(pairs.sample(t, renderer)[2][..., :3], np.asarray(target.bank.frames[t]),
                                   target.bank.keypoints[t]) for t in picks], axis=0)
    scores = trainer.validate()
    assert (scores["select_ssim"], scores["select_psnr"]) == pytest.approx(tuple(expected))


def test_a_run_saved_before_the_box_measure_scores_its_kept_checkpoint_again(tiny_target, tiny_config, tmp_path,
                                                                             monkeypatch):
    video, poses = tiny_target
    opts = dict(val_frames=2, sample_every=1000, checkpoint_every=3)
    with monkeypatch.context() as old:
        old.setattr(train_module, "SCORE_MEASURE", "whole crop at model size")
        _scripted_selection(old, {0: 0.99, 3: 0.5})  # the old measure's scale: later steps could never beat it
        train_video(video, tmp_path, "small", TrainOptions(epochs=1, max_steps=3, **opts), poses=poses,
                    device="cpu", overrides=tiny_config)
    meta = train_video(video, tmp_path, "small", TrainOptions(epochs=1, max_steps=2, **opts), resume=True,
                       poses=poses, device="cpu")
    best = meta["best"]
    assert best["measure"] == train_module.SCORE_MEASURE and best["select_ssim"] < 0.99
    rows = {r["step"]: float(r["select_ssim"]) for r in _rows(tmp_path / "validation.csv")}
    assert best["select_ssim"] == pytest.approx(max(rows["5"], best["select_ssim"]))


def test_bad_inputs_are_user_errors(tiny_target, tmp_path):
    video, poses = tiny_target
    with pytest.raises(DancesynthError, match="does not exist"):
        train_video(tmp_path / "nope.mp4", tmp_path / "r", options=TrainOptions(epochs=1))
    with pytest.raises(DancesynthError, match="--minutes"):
        train_video(video, tmp_path / "r", options=TrainOptions())
    with pytest.raises(DancesynthError):
        train_video(video, tmp_path / "r2", options=TrainOptions(epochs=1), resume=True)


def test_a_person_crossing_the_scene_gets_a_following_crop_and_the_background_condition(tmp_path, make_poses,
                                                                                           tiny_config):
    sway = make_poses(frames=24)
    kp = sway.keypoints.copy()
    kp[..., 0] += np.linspace(0, 200, 24)[:, None]  # walks 200 px across a 320-px scene
    seq = PoseSequence(kp, sway.fps, 320, 64)
    frames = [draw_pose(np.full((64, 320, 3), 90, np.uint8), k, thickness=3) for k in seq.keypoints]
    write_video(tmp_path / "walk.mp4", frames, seq.fps)
    seq.save(tmp_path / "walk.npz")
    meta = train_video(tmp_path / "walk.mp4", tmp_path / "run", "small", TrainOptions(epochs=1, max_steps=1,
                       val_frames=2), poses=tmp_path / "walk.npz", device="cpu", overrides=tiny_config)
    assert "follow" in meta["framing"] and meta["config"]["background"] and meta["config"]["blend"]


def test_a_person_dancing_on_the_spot_keeps_the_fixed_crop(tiny_run):
    meta = load_checkpoint(tiny_run, "stage2")[1]
    assert "follow" not in meta["framing"] and meta["config"]["prior"]
