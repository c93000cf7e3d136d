"""Forward kinematics: every method's `small` preset dances with bones that keep their length."""

import pytest
import torch

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)

from dancesynth.core.skeleton import ROOT  # noqa: E402
from stage1_pose.models.base import Batch  # noqa: E402
from stage1_pose.models.kinematics import (  # noqa: E402
    KinematicOutput,
    acceleration_loss,
    bone_vectors,
    forward_kinematics,
    joint_lengths,
    joint_speeds,
    motion_statistics_loss,
    speed_loss,
)
from stage1_pose.models.lstm.model import LSTMBaseline, LSTMConfig  # noqa: E402
from stage1_pose.registry import build_method, make_config  # noqa: E402

NON_ROOT = [j for j in range(25) if j != ROOT]


def test_a_pose_round_trips_through_its_bone_vectors():
    poses = torch.randn(3, 7, 25, 2)
    assert torch.allclose(forward_kinematics(bone_vectors(poses), joint_lengths(poses)), poses, atol=1e-5)


def test_any_output_gets_the_given_bones_and_keeps_the_root():
    raw, body = torch.randn(4, 9, 25, 2), torch.rand(25) + 0.1
    poses = forward_kinematics(raw, body)
    assert torch.allclose(joint_lengths(poses)[..., NON_ROOT], body[NON_ROOT].expand(4, 9, -1), atol=1e-5)
    assert torch.equal(poses[..., ROOT, :], raw[..., ROOT, :])
    # Model coordinates: a child of the root sits at its bone vector from MidHip, not from the canvas centre.
    assert torch.allclose(forward_kinematics(bone_vectors(poses), body), poses, atol=1e-5)


def test_the_generation_body_is_the_mean_of_the_training_clips():
    layer = KinematicOutput()
    small, large = (forward_kinematics(torch.randn(2, 5, 25, 2), torch.full((25,), s)) for s in (0.2, 0.4))
    assert torch.allclose(layer.observe(small)[..., NON_ROOT], torch.tensor(0.2), atol=1e-5)
    layer.observe(large)
    assert torch.allclose(layer.body[NON_ROOT], torch.tensor(0.3), atol=1e-5)
    layer.eval()
    layer.observe(small)
    assert torch.allclose(layer.body[NON_ROOT], torch.tensor(0.3), atol=1e-5) and int(layer.seen) == 2


def _inputs(name: str, frames: int) -> tuple[torch.Tensor, torch.Tensor]:
    dims = {"dance_revolution": 438, "lstm": 438, "dancing2music": 28, "ren": 1024}
    beats = torch.zeros(1, frames, dtype=torch.bool)
    beats[:, ::8] = True
    return torch.randn(1, frames, dims[name]), beats


@pytest.mark.parametrize("name", ["dance_revolution", "dancing2music", "ren", "lstm"])
def test_every_small_preset_dances_with_one_body(name):
    torch.manual_seed(0)
    config = make_config(name, "small")
    assert config.kinematic_output and not make_config(name, "paper").kinematic_output
    method = build_method(name, config).eval()
    features, beats = _inputs(name, 120)
    dance = method.generate(features, beats, torch.Generator().manual_seed(0))[0]
    lengths = joint_lengths(dance)[:, NON_ROOT]
    assert dance.shape == (120, 25, 2) and bool((lengths > 0).all())
    assert float((lengths.std(0) / lengths.mean(0)).max()) < 1e-4


def test_a_kinematic_model_learns_a_dance_and_keeps_its_body():
    torch.manual_seed(0)
    model = LSTMBaseline(LSTMConfig(feature_dim=6, hidden=32, layers=1, dropout=0.0, lr=1e-2, window_frames=16,
                                    kinematic_output=True, speed_weight=1.0))
    model._optimizers = model.configure_optimizers()
    t = torch.linspace(0, 6.28, 16)[:, None, None]
    raw = torch.randn(1, 1, 25, 2) + 0.5 * torch.sin(t + torch.arange(50.0).view(1, 25, 2))
    poses = forward_kinematics(raw, torch.rand(25) + 0.2)
    batch = Batch(torch.randn(1, 16, 6), torch.zeros(1, 16, dtype=torch.bool), poses, torch.zeros(1, dtype=torch.long))
    losses = [model.training_step(batch, 0)["l1"] for _ in range(200)]
    assert losses[-1] < losses[0] / 5
    model.eval()
    generated = model.generate(batch.features, batch.beats)
    assert torch.allclose(joint_lengths(generated), joint_lengths(poses[:, :1]).expand(1, 16, -1), atol=1e-4)


def test_joint_speeds_are_distances_per_frame_with_a_gradient_at_rest():
    poses = torch.zeros(1, 3, 25, 2)
    poses[0, 1:, 1] = torch.tensor([3.0, 4.0])  # joint 1 moves 5 units into frame 1, then rests
    poses.requires_grad_()
    speeds = joint_speeds(poses)
    assert speeds.shape == (1, 2, 25)
    torch.testing.assert_close(speeds[0, :, 1], torch.tensor([5.0, 0.0]), atol=1e-3, rtol=0)
    speeds.sum().backward()
    assert torch.isfinite(poses.grad).all()


def test_speed_and_acceleration_losses_see_a_shaking_root_in_every_joint():
    t = torch.linspace(0, 6.28, 30)[:, None, None]
    calm = (0.3 * torch.sin(t + torch.arange(50.0).view(25, 2)))[None]
    shaking = calm.clone()
    shaking[:, :, ROOT, 0] += 0.05 * (-1.0) ** torch.arange(30.0)
    assert float(speed_loss(calm, calm)) == 0.0 and float(acceleration_loss(calm, calm)) == 0.0
    # Only the root's row changed, yet on the canvas every joint shakes with it.
    per_joint = (joint_speeds(shaking) - joint_speeds(calm)).abs().mean(dim=(0, 1))
    assert bool((per_joint > 0.02).all())
    assert float(acceleration_loss(shaking, calm)) > 2 * float(speed_loss(shaking, calm)) > 0


def test_the_motion_statistics_loss_asks_for_the_amount_of_motion_not_its_timing():
    t = torch.arange(60.0)[:, None, None] * (6.2832 / 20)  # three whole periods of 20 frames
    real = (0.3 * torch.sin(t + torch.arange(50.0).view(25, 2)))[None]
    late = real.roll(5, dims=1)  # the same dance a quarter period later
    still = real[:, :1].expand_as(real)
    assert float(motion_statistics_loss(late, real)) < 0.02 < float(speed_loss(late, real))
    # Standing still misses all the speed and all the acceleration: 1 + 1.
    assert float(motion_statistics_loss(still, real)) == pytest.approx(2.0, abs=0.01)
    # Twice the motion is 100 % too much of each.
    assert float(motion_statistics_loss(2 * real - real[:, :1], real)) == pytest.approx(2.0, rel=1e-3)
    # A clip where the real dancer stands still costs what its motion is worth against the batch's, not infinity.
    pair_still = torch.cat([real, still])
    assert float(motion_statistics_loss(torch.cat([real, real]), pair_still)) == pytest.approx(2.0, abs=0.01)
    # One real clip sweeps, two hold still: moving at the mean speed everywhere fits, holding still (the median
    # clip) misses all of it.
    mixed = torch.cat([real, still, still])
    third = real[:, :1] + (real - real[:, :1]) / 3
    assert float(motion_statistics_loss(torch.cat([third] * 3), mixed)) < 0.01
    assert float(motion_statistics_loss(torch.cat([still] * 3), mixed)) == pytest.approx(2.0, abs=0.02)
