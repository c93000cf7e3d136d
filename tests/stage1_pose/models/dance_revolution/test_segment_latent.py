import pytest
import torch

from stage1_pose.models.dance_revolution.segment_latent import (
    SegmentPosterior,
    beat_segments,
    fixed_segments,
    kl_with_free_bits,
    per_frame,
    prior_codes,
)


def test_codes_are_held_through_their_segment():
    ids = fixed_segments(1, 10, every=4)
    assert ids.tolist() == [[0, 0, 0, 0, 1, 1, 1, 1, 2, 2]]
    codes = torch.arange(6.0).view(1, 3, 2)
    frames = per_frame(codes, ids)
    assert frames.shape == (1, 10, 2)
    assert torch.equal(frames[0, :4], codes[0, :1].expand(4, 2))
    assert torch.equal(frames[0, 8:], codes[0, 2:].expand(2, 2))


def test_a_segment_starts_at_every_beat():
    beats = torch.zeros(2, 9, dtype=torch.bool)
    beats[0, [0, 3, 7]] = True
    beats[1, 5] = True
    assert beat_segments(beats).tolist() == [[0, 0, 0, 1, 1, 1, 1, 2, 2], [0, 0, 0, 0, 0, 1, 1, 1, 1]]


def test_prior_codes_follow_the_seed_and_change_per_segment():
    ids = fixed_segments(2, 31, 15)
    a = prior_codes(ids, 4, torch.Generator().manual_seed(3))
    b = prior_codes(ids, 4, torch.Generator().manual_seed(3))
    c = prior_codes(ids, 4, torch.Generator().manual_seed(4))
    assert a.shape == (2, 31, 4) and torch.equal(a, b) and not torch.equal(a, c)
    assert torch.equal(a[:, 0], a[:, 14]) and not torch.equal(a[:, 14], a[:, 15])


def test_free_bits_leave_code_numbers_under_them_unpushed():
    kl = torch.tensor([0.1, 0.5, 2.0], requires_grad=True)
    assert kl_with_free_bits(kl, 0.0).item() == pytest.approx(2.6 / 3)
    cost = kl_with_free_bits(kl, 0.25)
    assert cost.item() == pytest.approx(2.75 / 3)
    cost.backward()
    assert kl.grad.tolist() == pytest.approx([0.0, 1 / 3, 1 / 3])


def test_posterior_gives_one_code_per_segment_and_a_differentiable_sample():
    posterior = SegmentPosterior(input_dim=50, dim=3)
    poses = torch.randn(2, 40, 50)
    beats = torch.zeros(2, 40, dtype=torch.bool)
    beats[0, [10, 20, 30]] = True
    beats[1, 25] = True
    ids = beat_segments(beats)
    mean, logvar, present = posterior(poses, ids)
    assert mean.shape == logvar.shape == (2, 4, 3)
    assert present.tolist() == [[True] * 4, [True, True, False, False]]
    codes, kl = posterior.sample(poses, ids)
    assert codes.shape == (2, 40, 3) and kl.shape == (3,)
    assert torch.equal(codes[0, 10], codes[0, 19]) and not torch.equal(codes[0, 19], codes[0, 20])
    (codes.sum() + kl.sum()).backward()
    assert all(p.grad is not None for p in posterior.parameters())
