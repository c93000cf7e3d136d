from dataclasses import replace

import pytest
import torch

from dancesynth.core.errors import DancesynthError
from stage1_pose.models.base import Batch
from stage1_pose.models.ren.model import (
    REN_PRESETS,
    GlobalContentDiscriminator,
    LocalTemporalDiscriminator,
    RenConfig,
    RenGenerator,
    RenMethod,
    StructuredSelfAttention,
    attention_penalty,
    frame_context,
    gradient_penalty,
    sub_sequences,
    temporal_difference,
)
from stage1_pose.models.ren.perceptual import PosePerceptualLoss
from stage1_pose.models.ren.stgcn import STGCN, STGCNConfig

S = 256  # samples per pose frame, small to keep the tests fast


def tiny(preset: str = "small", **kw) -> RenConfig:
    return replace(RenConfig.preset(preset), samples_per_frame=S, audio_channels=(4, 8, 8), code_dim=16,
                   gru_hidden=16, mlp_hidden=32, d_channels=8, d_embed=16, attention_dim=8, attention_hops=3,
                   window_frames=20, dropout=0.0, **kw)


def test_presets_cover_every_ablation_row():
    for size in ("small", "paper"):
        l1 = RenConfig.preset(f"l1-{size}")
        glob = RenConfig.preset(f"global_d-{size}")
        local = RenConfig.preset(f"local_d-{size}")
        full = RenConfig.preset(size)
        assert not (l1.uses_global_d or l1.uses_local_d or l1.uses_perceptual)
        assert glob.uses_global_d and not glob.uses_local_d and not glob.uses_perceptual
        assert local.uses_global_d and local.uses_local_d and not local.uses_perceptual
        assert full.uses_global_d and full.uses_local_d and full.uses_perceptual
    paper = REN_PRESETS["paper"]
    assert (paper.w_l1, paper.lr_g, paper.lr_d_local, paper.lr_d_global) == (200.0, 3e-4, 3e-4, 5e-4)
    assert paper.perceptual_layer_weights[:3] == (20.0, 5.0, 1.0)
    # The anti-jitter deviations are off in the paper preset.
    assert (paper.head_kernel, paper.w_velocity) == (1, 0.0)
    with pytest.raises(DancesynthError, match="Unknown ren preset"):
        RenConfig.preset("nope")


def test_module_shapes():
    cfg = tiny()
    audio, poses = torch.randn(2, 20, S), torch.randn(2, 20, 25, 2)
    beats = torch.zeros(2, 20, dtype=torch.bool)
    beats[:, ::6] = True
    out = RenGenerator(cfg)(audio, torch.randn(2, 20, cfg.noise_dim), beats=beats)
    assert out.shape == (2, 20, 25, 2)
    with pytest.raises(DancesynthError, match="beat flags"):
        RenGenerator(cfg)(audio, torch.randn(2, 20, cfg.noise_dim))
    # 16 windows of 5 frames for the official 50-frame windows; derived from the window length.
    assert sub_sequences(torch.randn(1, 50, 25, 2), 5, 3).shape == (1, 16, 5, 25, 2)
    assert LocalTemporalDiscriminator(cfg)(poses).shape == (2, (20 - 5) // 3 + 1)
    d = GlobalContentDiscriminator(cfg)
    f_m, attn = d.encode_music(audio)
    assert f_m.shape == (2, cfg.d_embed) and attn.shape == (2, cfg.attention_hops, 20)
    logit, feats = d.judge(poses, f_m)
    assert logit.shape == (2,) and len(feats) == 4
    assert d(poses, audio).shape == (2,)


def test_temporal_difference_of_linear_motion_is_constant():
    t = torch.arange(6.0).view(1, 1, 6, 1).expand(1, 2, 6, 25)
    assert torch.allclose(temporal_difference(t), torch.ones(1, 2, 6, 25))


def test_wrong_audio_piece_size_is_a_user_error():
    with pytest.raises(DancesynthError, match="samples per pose frame"):
        RenGenerator(tiny())(torch.randn(1, 10, S + 1), torch.randn(1, 10, 10))


def test_gradient_penalty_of_linear_critic():
    w = torch.tensor([3.0, 4.0, 0.0])  # ||w|| = 5, so the gradient norm is 5 at every interpolate
    critic = lambda x: (x * w).sum(dim=1)
    gp = gradient_penalty(critic, torch.randn(8, 3), torch.randn(8, 3))
    assert gp.item() == pytest.approx((5.0 - 1.0) ** 2)
    unit = lambda x: (x * (w / 5)).sum(dim=1)
    assert gradient_penalty(unit, torch.randn(4, 3), torch.randn(4, 3)).item() == pytest.approx(0.0, abs=1e-10)


def test_structured_self_attention_rows_and_penalty():
    att = StructuredSelfAttention(k=6, dim=4, hops=3)
    h = torch.randn(2, 7, 6)
    m, a = att(h)
    assert m.shape == (2, 3, 6) and a.shape == (2, 3, 7)
    assert torch.allclose(a.sum(-1), torch.ones(2, 3))
    assert torch.allclose(m, a @ h)
    orthonormal = torch.eye(3, 7).unsqueeze(0)  # one-hot rows on different steps: A A^T = I
    assert attention_penalty(orthonormal).item() == pytest.approx(0.0)
    uniform = torch.full((1, 3, 7), 1 / 7)
    assert attention_penalty(uniform).item() > 0.5


def test_full_training_step_updates_every_network():
    torch.manual_seed(0)
    method = RenMethod(tiny())
    method.perceptual = PosePerceptualLoss(STGCN(STGCNConfig.preset("small")), method.config.perceptual_layer_weights)
    method._optimizers = method.configure_optimizers()
    assert set(method._optimizers) == {"G", "D_local", "D_global"}
    before = {k: v.clone() for k, v in method.state_dict().items()}
    batch = Batch(torch.randn(3, 20, S), torch.zeros(3, 20, dtype=torch.bool), torch.randn(3, 20, 25, 2),
                  torch.tensor([0, 1, 2]))
    logs = method.training_step(batch, epoch=0)
    assert {"d_local", "d_global", "gp", "attn_penalty", "l1", "g_local", "g_global", "fm", "perceptual"} <= set(logs)
    assert all(torch.isfinite(torch.tensor(v)) for v in logs.values())
    after = method.state_dict()
    for prefix in ("generator.", "d_local.", "d_global."):
        assert any(not torch.equal(before[k], after[k]) for k in after if k.startswith(prefix)), prefix


def test_full_model_without_stgcn_run_says_what_to_do():
    with pytest.raises(DancesynthError, match="train-stgcn"):
        RenMethod(tiny()).configure_optimizers()


def test_l1_row_has_generator_only():
    method = RenMethod(tiny("l1-small"))
    assert method.d_local is None and method.d_global is None
    assert set(method.configure_optimizers()) == {"G"}


def test_generate_any_length_and_varies_with_seed():
    method = RenMethod(tiny("l1-small")).eval()
    audio, beats = torch.randn(1, 37, S), torch.zeros(1, 37, dtype=torch.bool)
    a = method.generate(audio, beats, torch.Generator().manual_seed(1))
    b = method.generate(audio, beats, torch.Generator().manual_seed(1))
    c = method.generate(audio, beats, torch.Generator().manual_seed(2))
    assert a.shape == (1, 37, 25, 2)
    assert torch.equal(a, b) and not torch.equal(a, c)


def test_tiny_generator_overfits_one_clip(rigid):
    # The small preset's kinematic output (bones of the clip's lengths); its speed loss is off to measure the L1.
    torch.manual_seed(0)
    method = RenMethod(tiny("l1-small", lr_g=3e-3, speed_weight=0.0))
    method._optimizers = method.configure_optimizers()
    t = torch.linspace(0, 6.28, 20)
    poses = rigid(torch.stack([torch.sin(t + j) for j in range(50)], dim=-1).view(1, 20, 25, 2))
    batch = Batch(torch.randn(1, 20, S), torch.zeros(1, 20, dtype=torch.bool), poses, torch.tensor([0]))
    first = method.training_step(batch, 0)["l1"]
    for _ in range(80):
        last = method.training_step(batch, 0)["l1"]
    assert last < 0.35 * first  # measured 0.29


def test_even_head_kernel_is_a_user_error():
    with pytest.raises(DancesynthError, match="head_kernel must be an odd"):
        RenGenerator(tiny(head_kernel=4))


def test_wide_head_kernel_generator_shapes():
    out = RenGenerator(tiny(head_kernel=9, beat_phase_input=False))(torch.randn(2, 3, S), torch.randn(2, 3, 10))
    assert out.shape == (2, 3, 25, 2)


def test_velocity_loss_only_where_configured():
    batch = Batch(torch.randn(2, 20, S), torch.zeros(2, 20, dtype=torch.bool), torch.randn(2, 20, 25, 2),
                  torch.tensor([0, 1]))
    for w, expected in ((1000.0, True), (0.0, False)):
        method = RenMethod(tiny("l1-small", w_velocity=w))
        method._optimizers = method.configure_optimizers()
        logs = method.training_step(batch, 0)
        assert ("velocity" in logs) == expected and (not expected or logs["velocity"] > 0)


def test_frame_context_stacks_neighbours_and_repeats_edges():
    x = torch.arange(4.0).view(1, 4, 1)
    assert frame_context(x, 1).equal(x)
    assert frame_context(x, 3)[0].tolist() == [[0, 0, 1], [0, 1, 2], [1, 2, 3], [2, 3, 3]]


def test_held_noise_is_smooth_with_the_configured_spread():
    method = RenMethod(tiny(noise_frames=10, noise_std=0.5))
    noise = method.sample_noise(400, 30, torch.device("cpu"), torch.Generator().manual_seed(0))
    assert noise.shape == (400, 30, method.config.noise_dim)
    assert torch.equal(noise, method.sample_noise(400, 30, torch.device("cpu"), torch.Generator().manual_seed(0)))
    std = noise.std(dim=(0, 2))
    assert torch.allclose(std, torch.full_like(std, 0.5), rtol=0.1)
    step = (noise[:, 1:] - noise[:, :-1]).abs().mean() / noise.abs().mean()
    fresh = RenMethod(tiny(noise_frames=1, noise_std=0.5)).sample_noise(400, 30, torch.device("cpu"))
    fresh_step = (fresh[:, 1:] - fresh[:, :-1]).abs().mean() / fresh.abs().mean()
    assert step < 0.3 < 1.0 < fresh_step


def two_mode_dances(move: torch.Tensor, variety_samples: int) -> list[torch.Tensor]:
    """Train the L1 row on one song danced two ways (``move`` and its mirror image); dances of 8 seeds. Free joint
    positions: the mean of the two ways is then a standstill (with kinematic output it is a body)."""
    torch.manual_seed(0)
    method = RenMethod(tiny("l1-small", lr_g=3e-3, noise_frames=20, noise_std=1.0, variety_samples=variety_samples,
                            kinematic_output=False, speed_weight=0.0, motion_weight=0.0))
    method._optimizers = method.configure_optimizers()
    audio, beats = torch.randn(1, 20, S).expand(2, -1, -1), torch.zeros(2, 20, dtype=torch.bool)
    batch = Batch(audio, beats, torch.stack([move, -move]), torch.tensor([0, 0]))
    for _ in range(300):
        method.training_step(batch, 0)
    method.eval()
    return [method.generate(audio[:1], beats[:1], torch.Generator().manual_seed(s))[0] for s in range(8)]


def test_variety_loss_makes_the_noise_choose_the_dance(mirrored_move, dances_one_way_or_the_other):
    size = mirrored_move.abs().mean()
    # Plain L1: every seed gives the mean of the two dances, a near-standstill.
    assert max(d.abs().mean() for d in two_mode_dances(mirrored_move, 1)) < 0.25 * size
    # Best of 4: every seed moves, most dance one of the two ways, and both ways occur.
    dances = two_mode_dances(mirrored_move, 4)
    assert min(d.abs().mean() for d in dances) > 0.5 * size
    assert dances_one_way_or_the_other(mirrored_move, dances, 0.5)


def test_noise_frames_and_variety_samples_must_be_positive():
    for field in ("noise_frames", "variety_samples"):
        with pytest.raises(DancesynthError, match="must be at least 1"):
            tiny(**{field: 0})



def test_beat_phase_input_times_the_moves_by_a_new_songs_beats(beat_following_error):
    # The paper's generator hears the beats only in the raw audio; with the beat phase it follows a new song's.
    def error(beat_phase_input: bool) -> float:
        config = replace(tiny("l1-small", kinematic_output=False, motion_weight=0.0, variety_samples=1,
                              beat_phase_input=beat_phase_input, lr_g=3e-3), window_frames=48)
        return beat_following_error(lambda: RenMethod(config), lambda beats: torch.randn(1, beats.shape[1], S))
    assert error(True) < 0.25  # measured 0.12
    assert error(False) > 0.4  # measured 0.71
