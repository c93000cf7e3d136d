import pytest
import torch

from stage1_pose.models.dance_revolution.local_attention import (
    LocalSelfAttention,
    band_mask,
    local_attention,
    masked_full_attention,
)

# The machine is shared: one intra-op thread avoids OpenMP contention that makes tiny ops take milliseconds.
torch.set_num_threads(1)


@pytest.mark.parametrize("n,window", [(1, 4), (7, 4), (50, 10), (53, 10), (64, 11), (30, 100), (41, 1), (33, 2)])
def test_local_equals_banded_full_attention(n, window):
    g = torch.Generator().manual_seed(n * 100 + window)
    q, k, v = (torch.randn(2, 3, n, d, generator=g, dtype=torch.float64) for d in (8, 8, 5))
    expected = masked_full_attention(q, k, v, band_mask(n, window))
    torch.testing.assert_close(local_attention(q, k, v, window), expected, rtol=1e-10, atol=1e-10)


def test_gradients_match_and_are_finite():
    g = torch.Generator().manual_seed(0)
    x = torch.randn(2, 23, 16, generator=g, dtype=torch.float64)
    local = LocalSelfAttention(16, heads=2, d_k=4, d_v=6, window=6).double()
    full = LocalSelfAttention(16, heads=2, d_k=4, d_v=6, window=6, full=True).double()
    full.load_state_dict(local.state_dict())
    grads = []
    for module in (local, full):
        xi = x.clone().requires_grad_(True)
        module(xi).square().sum().backward()
        grads.append(xi.grad)
    assert torch.isfinite(grads[0]).all()
    torch.testing.assert_close(grads[0], grads[1])


def test_band_width_is_window():
    # The output at position 0 must not change when frames beyond window // 2 change.
    attn = LocalSelfAttention(8, heads=2, d_k=4, d_v=4, window=6).eval()
    x = torch.randn(1, 20, 8)
    y = x.clone()
    y[:, 4:] += 10.0
    torch.testing.assert_close(attn(x)[:, 0], attn(y)[:, 0])
    y[:, 3] += 1.0
    assert not torch.allclose(attn(x)[:, 0], attn(y)[:, 0])
