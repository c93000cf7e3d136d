import math

import torch

from stage1_pose.models.beat_clock import beat_phase, phase_features


def flags(frames: int, *rows: list[int]) -> torch.Tensor:
    out = torch.zeros(len(rows), frames, dtype=torch.bool)
    for r, at in enumerate(rows):
        out[r, at] = True
    return out


def test_phase_rises_from_each_beat_to_the_next():
    phase = beat_phase(flags(12, [2, 6, 8]))[0]
    assert torch.allclose(phase[2:8], torch.tensor([0.0, 0.25, 0.5, 0.75, 0.0, 0.5]))


def test_first_and_last_intervals_continue_outwards():
    phase = beat_phase(flags(12, [2, 6, 8]))[0]
    assert torch.allclose(phase[:2], torch.tensor([0.5, 0.75]))  # the 4-frame interval, counted backwards
    assert torch.allclose(phase[8:], torch.tensor([0.0, 0.5, 0.0, 0.5]))  # the 2-frame interval onwards


def test_rows_with_fewer_than_two_beats_count_in_the_fallback_period():
    phase = beat_phase(flags(10, [5], []), fallback_period=4.0)
    assert torch.allclose(phase[0], torch.tensor([0.75, 0.0, 0.25, 0.5, 0.75, 0.0, 0.25, 0.5, 0.75, 0.0]))
    assert torch.allclose(phase[1], torch.tensor([0.0, 0.25, 0.5, 0.75, 0.0, 0.25, 0.5, 0.75, 0.0, 0.25]))


def test_features_are_continuous_across_the_beat():
    feats = phase_features(torch.tensor([[0.0, 0.25, 0.999]]))
    assert feats.shape == (1, 3, 2)
    assert torch.allclose(feats[0, 1], torch.tensor([1.0, 0.0]), atol=1e-6)
    assert (feats[0, 2] - feats[0, 0]).norm() < 2 * math.pi * 0.002
