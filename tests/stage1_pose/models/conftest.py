from collections.abc import Callable

import pytest
import torch

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


@pytest.fixture
def dance_on_the_beats() -> Callable[[torch.Tensor, torch.Tensor], torch.Tensor]:
    """``dance(beats [1, T], shape [50])`` -> ``[1, T, 25, 2]``: the body swings out to ``shape`` and back in every
    beat interval, still on the beats."""
    def dance(beats: torch.Tensor, shape: torch.Tensor) -> torch.Tensor:
        phase = beat_phase(beats)
        return ((1 - torch.cos(2 * torch.pi * phase))[..., None] / 2 * shape).reshape(1, -1, 25, 2)
    return dance
