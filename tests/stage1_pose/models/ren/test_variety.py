import pytest
import torch
import torch.nn.functional as F

from stage1_pose.models.ren.variety import best_of


def test_best_of_picks_the_closest_draw_per_example():
    target = torch.zeros(2, 5, 3)
    preds = torch.stack([torch.full((2, 5, 3), 1.0), torch.full((2, 5, 3), -0.5)])
    preds[1, 1] = 3.0  # example 1: the first draw is the closer one
    best, l1 = best_of(preds, target)
    assert torch.equal(best[0], preds[1, 0]) and torch.equal(best[1], preds[0, 1])
    assert l1.item() == pytest.approx(F.l1_loss(best, target).item()) == pytest.approx(0.75)


def test_gradient_reaches_only_the_chosen_draws():
    preds = torch.tensor([[[1.0, 1.0]], [[0.1, -0.1]], [[2.0, 0.0]]], requires_grad=True)
    best_of(preds, torch.zeros(1, 2))[1].backward()
    assert preds.grad[0].abs().sum() == 0 and preds.grad[2].abs().sum() == 0
    assert preds.grad[1].abs().sum() > 0


def test_one_draw_is_the_plain_l1_loss():
    preds, target = torch.randn(1, 4, 6, 2), torch.randn(4, 6, 2)
    best, l1 = best_of(preds, target)
    assert torch.equal(best, preds[0]) and l1.item() == pytest.approx(F.l1_loss(preds[0], target).item())


def test_mismatched_shapes_are_refused():
    with pytest.raises(ValueError, match="must be"):
        best_of(torch.randn(2, 3, 4), torch.randn(3, 5))
