import json
import shutil

import numpy as np
import pytest
import torch

from dancesynth.core import device as device_module
from dancesynth.core.checkpoint import load_checkpoint, update_meta
from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import probe_video
from dancesynth.core.skeleton import PoseSequence
from stage2_video.framing import condition
from stage2_video.prior import PriorRenderer
from stage2_video.render import (
    CONVERTED_DIR,
    OpenVINOGenerator,
    load_appearance_model,
    render_frames,
    render_layers,
    render_video,
)
from stage2_video.train import TrainOptions, train_video
from stage2_video.training_data import EXCLUDE_SECONDS, prior_images


def test_render_streams_a_video_with_right_count_and_size(tiny_run, tiny_target, make_poses, tmp_path):
    model = load_appearance_model(tiny_run, "cpu")
    # poses from elsewhere: another canvas, smaller person, other fps -> resampled and normalised onto the target
    src = make_poses(frames=9, width=200, height=120)
    src = src.replace(src.keypoints * np.array([0.8, 0.8, 1], np.float32), fps=10.0)
    crop, scene, side = tmp_path / "crop.mp4", tmp_path / "scene.mp4", tmp_path / "side.mp4"
    made = render_video(src, model, crop, crop=True, progress=False)
    info = probe_video(crop)
    assert model.scale == 2 and (info.width, info.height) == (64, 64)  # the prior's size
    # 0.9 s at the target video's frame rate
    assert info.num_frames == len(made.poses) == round(0.9 * model.fps) and info.fps == pytest.approx(model.fps)
    assert (made.poses.width, made.poses.height) == model.canvas and made.written == [crop]
    render_video(src, model, scene, height=48, side_by_side=side, progress=False)
    target = probe_video(tiny_target[0])
    assert probe_video(scene).height == 48 and probe_video(side).width == 2 * probe_video(scene).width
    assert abs(probe_video(scene).width / 48 - target.width / target.height) < 0.05
    assert not list(tmp_path.glob("*.part*"))


def test_crop_with_height_is_refused(tiny_run, make_poses, tmp_path):
    with pytest.raises(DancesynthError, match="use one of them"):
        render_video(make_poses(frames=3), load_appearance_model(tiny_run, "cpu"), tmp_path / "x.mp4", crop=True,
                     height=64)
    assert not list(tmp_path.iterdir())


def test_optimized_generator_matches_plain_forward(tiny_run):
    fast = load_appearance_model(tiny_run, "cpu", precision="fp32")
    plain = load_appearance_model(tiny_run, "cpu", optimize=False, precision="fp32")
    assert isinstance(fast.generator, OpenVINOGenerator) and isinstance(plain.generator, torch.nn.Module)
    poses = PoseSequence.load(tiny_run / "poses.npz").slice_frames(0, 5)
    for a, b in zip(render_frames(fast, poses), render_frames(plain, poses)):
        assert a.shape == (64, 64, 3) and a.dtype == np.uint8
        assert np.abs(a.astype(int) - b.astype(int)).max() <= 1


def test_the_converted_network_is_kept_with_the_model_until_its_weights_change(tiny_run, tiny_target, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, ignore=shutil.ignore_patterns(CONVERTED_DIR))
    poses = PoseSequence.load(run / "poses.npz").slice_frames(0, 5)
    first = list(render_frames(load_appearance_model(run, "cpu", precision="fp32"), poses))
    key = run / CONVERTED_DIR / "key.txt"
    written = key.stat().st_mtime_ns
    # Read back, not converted again: the same frames.
    again = list(render_frames(load_appearance_model(run, "cpu", precision="fp32"), poses))
    assert key.stat().st_mtime_ns == written and all(np.array_equal(a, b) for a, b in zip(first, again))
    # Trained further, the model is converted again and renders its new weights.
    video, pose_file = tiny_target
    train_video(video, run, "small", TrainOptions(epochs=2, max_steps=1, val_frames=4), resume=True, poses=pose_file,
                device="cpu")
    fast = load_appearance_model(run, "cpu", precision="fp32")
    plain = load_appearance_model(run, "cpu", optimize=False, precision="fp32")
    assert key.stat().st_mtime_ns != written
    for a, b in zip(render_frames(fast, poses), render_frames(plain, poses)):
        assert np.abs(a.astype(int) - b.astype(int)).max() <= 1
    # A damaged copy is converted again rather than read.
    (run / CONVERTED_DIR / "generator.bin").write_bytes(b"")
    damaged = list(render_frames(load_appearance_model(run, "cpu", precision="fp32"), poses))
    assert all(np.abs(a.astype(int) - b.astype(int)).max() <= 1 for a, b in zip(damaged, render_frames(plain, poses)))
    assert (run / CONVERTED_DIR / "generator.bin").stat().st_size > 0


def test_a_converted_network_that_cannot_be_kept_still_renders_and_leaves_nothing(tiny_run, tmp_path, monkeypatch):
    import openvino

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, ignore=shutil.ignore_patterns(CONVERTED_DIR))

    def disk_full(*args, **kwargs):
        raise RuntimeError("No space left on device")

    monkeypatch.setattr(openvino, "save_model", disk_full)
    poses = PoseSequence.load(run / "poses.npz").slice_frames(0, 3)
    assert len(list(render_frames(load_appearance_model(run, "cpu", precision="fp32"), poses))) == 3
    assert not [p.name for p in run.iterdir() if "openvino" in p.name]


@pytest.mark.parametrize("optimize", [True, False])
def test_bf16_rendering_stays_close_to_fp32(tiny_run, monkeypatch, optimize):
    # On a CPU without bf16 instructions OpenVINO keeps f32 and PyTorch's bf16 autocast still runs.
    monkeypatch.setattr(device_module, "cpu_has_bf16", lambda: True)
    exact = load_appearance_model(tiny_run, "cpu", optimize=optimize, precision="fp32")
    fast = load_appearance_model(tiny_run, "cpu", optimize=optimize, precision="bf16")
    poses = PoseSequence.load(tiny_run / "poses.npz").slice_frames(0, 8)
    previous, renderer = None, PriorRenderer(exact.bank)
    # Both conditioned on the fp32 previous frame: the barely trained network amplifies differences through its
    # recursion, which a trained one does not.
    for keypoints in poses.keypoints:
        high, low = prior_images(renderer, keypoints, exact.output_framing(exact.framing), exact.plate, (32, 32))
        label = condition(keypoints, exact.framing, exact.plate, low)
        reference, a, _ = exact.step_with_prior(label, high, previous)
        b = fast.step_with_prior(label, high, previous)[1]
        diff = np.abs(a.astype(int) - b.astype(int))
        # Measured 0.35-0.51 grey levels on average and 4 at most.
        assert diff.mean() < 1 and diff.max() <= 8
        previous = reference


def test_wrong_kind_checkpoint_is_a_user_error(tiny_run, tmp_path):
    other = tmp_path / "other"
    other.mkdir()
    for f in tiny_run.glob("latest.*"):
        (other / f.name).write_bytes(f.read_bytes())
    meta = json.loads((other / "latest.json").read_text())
    meta["kind"] = "stage1"
    (other / "latest.json").write_text(json.dumps(meta))
    with pytest.raises(DancesynthError):
        load_appearance_model(other, "cpu")
    with pytest.raises(DancesynthError):
        load_appearance_model(tmp_path / "missing", "cpu")


def test_a_model_trained_before_the_warped_prior_still_loads_and_renders(tiny_target, tiny_config, tmp_path):
    video, poses = tiny_target
    run = tmp_path / "old"
    train_video(video, run, "small", TrainOptions(epochs=1, max_steps=1, val_frames=2), poses=poses, device="cpu",
                overrides={**tiny_config, "background": False, "blend": False, "prior": False})
    meta = load_checkpoint(run, "stage2")[1]
    # Its saved config as written before the prior existed: no prior fields at all.
    update_meta(run, "stage2", {"config": {k: v for k, v in meta["config"].items() if not k.startswith("prior")}})
    model = load_appearance_model(run, "cpu")
    assert model.bank is None and model.scale == 1
    render_video(PoseSequence.load(poses).slice_frames(0, 4), model, tmp_path / "old.mp4", normalize=False,
                 crop=True, progress=False)
    info = probe_video(tmp_path / "old.mp4")
    assert (info.width, info.height, info.num_frames) == (32, 32, 4)


def test_a_prior_model_painted_through_a_mask_still_loads_and_renders(tiny_target, tiny_config, tmp_path):
    video, poses = tiny_target
    run = tmp_path / "masked"
    train_video(video, run, "small", TrainOptions(epochs=1, max_steps=1, val_frames=2), poses=poses, device="cpu",
                overrides={**tiny_config, "residual": False, "select_fraction": 0.0})
    meta = load_checkpoint(run, "stage2")[1]
    # Its saved config as written before residual corrections, selection frames and the median prior existed.
    update_meta(run, "stage2", {"config": {k: v for k, v in meta["config"].items()
                                           if k not in ("residual", "select_fraction", "prior_candidates")}})
    model = load_appearance_model(run, "cpu")
    assert model.config.prior and not model.config.repairs and model.generator is not None
    assert model.bank.candidates == 1  # warped from one frame, as it was trained
    frames = list(render_frames(model, PoseSequence.load(poses).slice_frames(0, 3)))
    assert len(frames) == 3 and frames[0].shape == (64, 64, 3)


def test_an_untrained_prior_model_renders_the_warp_alone(tiny_target, tiny_config, tmp_path):
    video, poses = tiny_target
    run = tmp_path / "zero"
    meta = train_video(video, run, "small", TrainOptions(minutes=0), poses=poses, device="cpu", overrides=tiny_config)
    assert meta["step"] == 0 and meta["trained_seconds"] == 0
    model = load_appearance_model(run, "cpu")
    assert model.generator is None
    seq = PoseSequence.load(poses).slice_frames(0, 3)
    renderer = PriorRenderer(model.bank)
    for keypoints, frame in zip(seq.keypoints, render_frames(model, seq)):
        high, _ = prior_images(renderer, keypoints, model.output_framing(model.framing), model.plate, (32, 32))
        assert np.array_equal(frame, high[..., :3])


def test_a_model_renders_its_own_training_frames_as_training_warps_them(tiny_target, tiny_config, tmp_path):
    video, poses = tiny_target
    run = tmp_path / "zero"
    train_video(video, run, "small", TrainOptions(minutes=0), poses=poses, device="cpu", overrides=tiny_config)
    model = load_appearance_model(run, "cpu")
    seq = PoseSequence.load(poses).slice_frames(4, 8)
    window = round(EXCLUDE_SECONDS * seq.fps)
    choices, chosen = model.bank.choices, []

    def spy(query, count, exclude=None, previous=None, scene=None):
        chosen.append((exclude, choices(query, count, exclude, previous, scene)))
        scenes.append(scene)
        return chosen[-1][1]

    scenes = []
    model.bank.choices = spy
    list(render_layers(model, seq, first_frame=4))
    assert [e for e, _ in chosen] == [(t - window, t + window + 1) for t in range(4, 8)]
    # retrieval compares places in the video's pixels: the poses as given, not as framed
    np.testing.assert_array_equal(np.stack(scenes), seq.keypoints)
    chosen.clear()
    list(render_layers(model, seq))  # rendering a new dance may take any bank frame
    assert all(e is None for e, _ in chosen)
