import pytest
import torch

from stage1_pose.models.gaussian import kl_to_standard_normal, reparameterize


def test_kl_is_zero_only_for_the_standard_normal():
    zero = torch.zeros(3, 4)
    assert torch.equal(kl_to_standard_normal(zero, zero, mean_over=0), torch.zeros(4))
    assert kl_to_standard_normal(zero + 1, zero, mean_over=0).tolist() == pytest.approx([0.5] * 4)
    assert (kl_to_standard_normal(zero, zero - 2, mean_over=0) > 0).all()
    means = torch.zeros(3, 4)
    means[:, 1] = 2.0
    assert kl_to_standard_normal(means, zero, mean_over=0).tolist() == pytest.approx([0.0, 2.0, 0.0, 0.0])


def test_kl_over_everything_is_the_mean_per_latent_number():
    means = torch.zeros(3, 4)
    means[:, 1] = 2.0
    # A scalar that does not grow with the latent size: the mean of the per-number KLs [0, 2, 0, 0].
    assert kl_to_standard_normal(means, torch.zeros(3, 4)).item() == pytest.approx(0.5)
    assert kl_to_standard_normal(torch.zeros(2, 40), torch.zeros(2, 40)).item() == 0.0


def test_reparameterized_samples_follow_the_gaussian_and_carry_gradients():
    torch.manual_seed(0)
    mean = torch.full((20000, 2), 3.0, requires_grad=True)
    logvar = torch.log(torch.tensor([0.25, 4.0])).expand(20000, 2).clone().requires_grad_()
    z = reparameterize(mean, logvar)
    assert z.mean(0).tolist() == pytest.approx([3.0, 3.0], abs=0.05)
    assert z.std(0).tolist() == pytest.approx([0.5, 2.0], rel=0.05)
    z.sum().backward()
    assert torch.equal(mean.grad, torch.ones_like(mean)) and logvar.grad.abs().sum() > 0
