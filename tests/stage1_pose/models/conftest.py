from collections.abc import Callable

import pytest
import torch

from stage1_pose.models.base import Batch, Stage1Method
from stage1_pose.models.beat_clock import beat_phase
from stage1_pose.models.kinematics import bone_vectors, forward_kinematics, joint_lengths


@pytest.fixture
def rigid() -> Callable[[torch.Tensor], torch.Tensor]:
    """``rigid(poses)``: ``[..., T, 25, 2]`` poses with every frame's bones at the first frame's lengths, directions
    kept: a dance a kinematic output layer (the `small` presets') can reproduce exactly, like the built-in dances."""
    return lambda poses: forward_kinematics(bone_vectors(poses), joint_lengths(poses[..., :1, :, :]))


@pytest.fixture
def mirrored_move() -> torch.Tensor:
    """A 20-frame move ``[20, 25, 2]`` (model coordinates); the same song danced two ways is it and its negative."""
    t = torch.linspace(0, 6.28, 20)
    return torch.stack([torch.sin(t + j) for j in range(50)], dim=-1).view(20, 25, 2) * 0.5


@pytest.fixture
def dances_one_way_or_the_other() -> Callable[[torch.Tensor, list[torch.Tensor], float], bool]:
    """``check(move, dances, tolerance)``: the median dance is within ``tolerance`` x the move's size of the move
    or its mirror image, and both ways occur."""
    def check(move: torch.Tensor, dances: list[torch.Tensor], tolerance: float) -> bool:
        nearest = torch.stack([min((d - move).abs().mean(), (d + move).abs().mean()) for d in dances])
        both = {int(torch.sign((d * move).sum())) for d in dances} == {-1, 1}
        return bool(nearest.median() < tolerance * move.abs().mean()) and both
    return check


def beat_flags(intervals: list[int], frames: int) -> torch.Tensor:
    """``[1, frames]`` beat flags repeating ``intervals`` (frames), the first beat on frame 0."""
    beats = torch.zeros(1, frames, dtype=torch.bool)
    at = torch.tensor(intervals).repeat(frames).cumsum(0) - intervals[0]
    beats[0, at[at < frames]] = True
    return beats


def dance_on_the_beats(beats: torch.Tensor, shape: torch.Tensor) -> torch.Tensor:
    """``[1, T, 25, 2]``: the body swings out to ``shape`` (``[50]``) and back in every beat interval of ``[1, T]``
    beat flags, still on the beats."""
    phase = beat_phase(beats)
    return ((1 - torch.cos(2 * torch.pi * phase))[..., None] / 2 * shape).reshape(1, -1, 25, 2)


@pytest.fixture
def beat_following_error() -> Callable[..., float]:
    """``error(make_method, features_for, steps=150, epoch=0)``: train ``make_method()`` for ``steps`` steps on one
    48-frame song with uneven beats (``features_for(beats [1, T]) -> [1, T, D]``) whose dance swings on the beats;
    the relative L1 error of the dance it generates for a song with other beats (0 = it follows the new beats)."""
    def error(make_method: Callable[[], Stage1Method], features_for: Callable[[torch.Tensor], torch.Tensor],
              steps: int = 150, epoch: int = 0) -> float:
        torch.manual_seed(0)
        shape = torch.randn(50) * 0.5
        method = make_method()
        method._optimizers = method.configure_optimizers()
        beats = beat_flags([4, 7, 5, 8, 6], 48)
        batch = Batch(features_for(beats), beats, dance_on_the_beats(beats, shape), torch.zeros(1, dtype=torch.long))
        for _ in range(steps):
            method.training_step(batch, epoch)
        new_beats = beat_flags([6, 9, 5], 48)
        wanted = dance_on_the_beats(new_beats, shape)
        generated = method.eval().generate(features_for(new_beats), new_beats, torch.Generator().manual_seed(0))
        return float((generated - wanted).abs().mean() / wanted.abs().mean())
    return error
