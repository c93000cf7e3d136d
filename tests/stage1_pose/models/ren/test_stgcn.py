import numpy as np
import pytest
import torch

from dancesynth.core.skeleton import BODY25_LIMBS, NECK, ROOT
from stage1_pose.models.ren.stgcn import STGCN, STGCNConfig, spatial_adjacency, to_absolute


def test_spatial_adjacency_partitions_body25_graph():
    adj = spatial_adjacency()
    assert adj.shape == (3, 25, 25)
    np.testing.assert_allclose(adj.sum(axis=(0, 2)), 1.0, rtol=1e-6)  # each joint averages its neighbourhood
    assert adj[0, NECK, NECK] > 0  # self loop sits in the root partition
    a, b = 1, 8  # Neck -> MidHip: MidHip is one hop farther from the centre
    assert adj[2, a, b] > 0 and adj[1, b, a] > 0
    linked = (adj.sum(axis=0) > 0)
    for i, j in BODY25_LIMBS:
        assert linked[i, j] and linked[j, i]
    assert linked.sum() == 25 + 2 * len(BODY25_LIMBS)


def test_to_absolute_adds_root_to_relative_joints():
    poses = torch.zeros(1, 2, 25, 2)
    poses[..., ROOT, :] = torch.tensor([1.0, -2.0])
    poses[..., NECK, :] = torch.tensor([0.0, -1.0])
    out = to_absolute(poses)
    assert torch.allclose(out[..., NECK, :], torch.tensor([1.0, -3.0]))
    assert torch.allclose(out[..., ROOT, :], torch.tensor([1.0, -2.0]))


@pytest.mark.parametrize("frames", [9, 20])
def test_stgcn_shapes(frames):
    cfg = STGCNConfig.preset("small").with_classes(4)
    net = STGCN(cfg)
    x = torch.randn(3, frames, 25, 2)
    feats = net.features(x)
    assert len(feats) == len(cfg.channels)
    assert [f.shape[1] for f in feats] == list(cfg.channels)
    assert feats[-1].shape[-1] == 25 and feats[-1].shape[2] == -(-frames // 2)
    assert net(x).shape == (3, 4)


def test_paper_preset_is_ten_blocks():
    cfg = STGCNConfig.preset("paper")
    assert len(cfg.channels) == 10 and cfg.lr == 2e-3
    with pytest.raises(KeyError):
        STGCNConfig.preset("huge")
