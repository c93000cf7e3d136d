from dataclasses import replace

import numpy as np
import pytest
import torch

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import ROOT
from stage1_pose.models.base import Batch
from stage1_pose.models.dancing2music import dance_units as du
from stage1_pose.models.dancing2music.model import (
    DANCING2MUSIC_PRESETS,
    POSE_DIM,
    Dancing2MusicConfig,
    Dancing2MusicMethod,
    absolute_positions,
    keep_on_stage,
    shift_root,
    unit_motion,
)

# Free joint positions: these tests follow the paper's units (the small preset's kinematic output has its own tests).
TINY = replace(DANCING2MUSIC_PRESETS["small"], gru_hidden=32, mlp_hidden=32, z_mov=8, z_dan=8, noise_dim=4,
               lr=3e-3, epochs=2, decomp_epochs=1, kinematic_output=False, epoch_windows=0, speed_weight=0.0,
               steady_energy=0.0)  # the redraw tests read the floor alone; steady energy has its own test


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """These tiny recurrent nets run several times faster on one thread than on contended cores."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _dance(frames: int, period: float, phase: float = 0.0) -> np.ndarray:
    """``[T, 25, 2]`` model coordinates: a body whose arms swing with ``period`` frames (kinematic beats at the
    turning points) and whose root sways slowly."""
    t = np.arange(frames)[:, None]
    rng = np.random.default_rng(0)
    base = rng.normal(0, 0.6, (25, 2))
    pose = np.repeat(base[None], frames, axis=0)
    swing = np.sin(2 * np.pi * t / period + phase)
    pose[:, [3, 4, 6, 7], 1] += 0.8 * swing
    pose[:, [3, 4, 6, 7], 0] += 0.3 * swing
    pose[:, ROOT, 0] = 0.2 * np.sin(2 * np.pi * t[:, 0] / (4 * period))
    return pose.astype(np.float32)


def _batch(b: int = 4, frames: int = 240) -> Batch:
    poses = np.stack([_dance(frames, 15.0 + k, k) for k in range(b)])
    features = np.random.default_rng(1).normal(size=(b, frames, 28)).astype(np.float32)
    beats = torch.zeros(b, frames, dtype=torch.bool)
    return Batch(torch.from_numpy(features), beats, torch.from_numpy(poses), torch.arange(b) % 3)


def _beat_flags(frames: int, *beat_frames: np.ndarray) -> torch.Tensor:
    """``[len(beat_frames), frames]`` beat flags at the given frame positions (rounded)."""
    flags = torch.zeros(len(beat_frames), frames, dtype=torch.bool)
    for row, at in zip(flags, beat_frames):
        row[torch.from_numpy(np.round(at).astype(np.int64))] = True
    return flags


@pytest.fixture(scope="module")
def trained(one_thread) -> Dancing2MusicMethod:
    """A tiny model after a few steps of each phase."""
    torch.manual_seed(0)
    model = Dancing2MusicMethod(TINY)
    model._optimizers = model.configure_optimizers()
    batch = _batch()
    for epoch in (0, 0, 1, 1):
        model.training_step(batch, epoch)
    return model.eval()


def test_network_shapes():
    torch.manual_seed(0)
    m = Dancing2MusicMethod(TINY)
    units = torch.randn(6, du.UNIT_FRAMES, POSE_DIM)
    mu_i, lv_i = m.e_ini(units[:, 0])
    mu_m, lv_m = m.e_mov(units)
    assert mu_i.shape == lv_i.shape == (6, TINY.z_ini) and mu_m.shape == lv_m.shape == (6, TINY.z_mov)
    assert m.g_uni(mu_i, mu_m).shape == (6, du.UNIT_FRAMES, POSE_DIM)
    anchor = torch.randn(6, POSE_DIM)
    assert torch.allclose(m.g_uni(mu_i, mu_m, anchor)[:, 0], anchor, atol=1e-5)
    logits, s = m.style(torch.randn(6, 50, 28))
    assert logits.shape == (6, 3) and s.shape == (6, TINY.style_hidden)
    z_movs = torch.randn(2, 4, TINY.z_mov)
    mu_d, _ = m.e_mtd(z_movs)
    assert mu_d.shape == (2, TINY.z_dan)
    assert m.g_dan(mu_d, 5).shape == (2, 5, TINY.z_mov)
    assert m.e_std(torch.randn(2, TINY.style_hidden), torch.randn(2, TINY.noise_dim)).shape == (2, TINY.z_dan)
    assert m.e_sty(mu_d).shape == (2, TINY.style_hidden)
    assert m.d_mov(z_movs, torch.randn(2, 4, du.UNIT_FRAMES, 28)).shape == (2,)
    assert m.d_dan(mu_d).shape == (2, 1)


def test_paper_preset_sizes_and_ablation():
    paper = Dancing2MusicConfig.preset("paper")
    assert (paper.gru_hidden, paper.z_mov, paper.z_ini, paper.z_dan) == (1024, 512, 10, 512)
    assert (paper.w_kl, paper.w_shift, paper.w_adv, paper.w_style, paper.lr, paper.betas) == (
        0.01, 1.0, 0.1, 1.0, 1e-4, (0.5, 0.999))
    nocomp = Dancing2MusicMethod(replace(TINY, composition=False, decomp_epochs=TINY.epochs))
    assert set(nocomp.configure_optimizers()) == {"vae", "style"}
    assert nocomp.phase(10 ** 6) == "decomposition"
    with pytest.raises(DancesynthError, match="Unknown dancing2music preset"):
        Dancing2MusicConfig.preset("huge")
    # The paper's warper puts the normalised unit beats on the music beats; the CPU preset also aligns and accents.
    assert (paper.warp_stretch, paper.beat_accent) == (1.0, 0.0)
    small = Dancing2MusicConfig.preset("small-nocomp")
    assert small.warp_stretch > 1 and 0 < small.beat_accent < 1
    with pytest.raises(DancesynthError, match="beat_accent"):
        replace(TINY, beat_accent=1.0)


def test_shift_moves_only_the_root():
    units = torch.randn(3, du.UNIT_FRAMES, 25, 2)
    moved = shift_root(units, torch.ones(3, 2))
    assert torch.allclose((moved - units)[:, :, ROOT], torch.ones(3, du.UNIT_FRAMES, 2))
    assert torch.equal(torch.cat([moved[:, :, :ROOT], moved[:, :, ROOT + 1:]], 2),
                       torch.cat([units[:, :, :ROOT], units[:, :, ROOT + 1:]], 2))
    poses = np.random.default_rng(0).normal(size=(4, 25, 2))
    absolute = absolute_positions(poses)
    np.testing.assert_allclose(absolute[:, 0] - absolute[:, ROOT], poses[:, 0])


def test_a_dancer_who_walks_off_keeps_their_place_and_their_steps():
    t = torch.arange(900, dtype=torch.float32)
    dance = torch.randn(900, 25, 2) * 0.1
    step = 0.3 * torch.sin(2 * torch.pi * t / 15)  # a step to the side and back every second
    dance[:, ROOT, 0] = 0.01 * t + step  # ... while walking 9 torso lengths off in a minute
    kept = keep_on_stage(dance, sigma=30.0)
    root = kept[:, ROOT, 0]
    assert float(root.abs().max()) < 0.6  # within two steps' reach of the start (the walk went 9 away)
    # The step stays (its swing keeps nearly all of its range), and only the root moves.
    assert float(root[300:600].max() - root[300:600].min()) > 0.55
    assert torch.equal(kept[:, :ROOT], dance[:, :ROOT]) and torch.equal(kept[:, ROOT + 1:], dance[:, ROOT + 1:])


def test_tiny_du_vae_learns_to_reconstruct_units_and_to_continue_its_own():
    torch.manual_seed(0)
    model = Dancing2MusicMethod(TINY)
    model._optimizers = model.configure_optimizers()
    poses = _dance(200, 15.0)
    beats = np.arange(2, 190, 7.5)
    units = torch.from_numpy(du.cut_units(poses, du.unit_runs(beats, 3, 20)[0]))
    follows = torch.arange(len(units) - 1)  # one run: every unit but the last has a successor
    first = model.decomposition_losses(units, follows)
    for _ in range(300):
        model.optimize("vae", model.decomposition_losses(units, follows)["total"])
    last = model.decomposition_losses(units, follows)
    assert last["recon"].item() < min(0.1, first["recon"].item() / 4), (first, last)
    # The chained unit starts from a reconstructed frame, not the true one: it learns to rejoin the real dance.
    assert last["chain"].item() < first["chain"].item() / 2, (first, last)
    assert model.decomposition_losses(units)["chain"].item() == 0.0


def test_training_steps_cover_both_phases(trained):
    assert trained.phase_steps.tolist()[0] >= 1 and trained.phase_steps.tolist()[1] >= 1
    assert trained.curriculum_state() == {"phase_steps": trained.phase_steps.tolist()}
    assert 3.0 <= float(trained.beat_interval) <= 20.0


def test_generation_length_and_seeds(trained):
    features = torch.from_numpy(np.random.default_rng(2).normal(size=(2, 97, 28)).astype(np.float32))
    beats = _beat_flags(97, np.arange(3.0, 97.0, 7.0), np.arange(1.0, 97.0, 8.5))

    def gen(seed):
        return trained.generate(features, beats, torch.Generator().manual_seed(seed))

    a, b, c = gen(0), gen(0), gen(1)
    assert a.shape == (2, 97, 25, 2)
    assert torch.equal(a, b)
    assert (a - c).abs().mean() > 1e-3
    assert torch.isfinite(a).all()


def test_one_style_for_the_whole_song(trained):
    # A real song's intro and its rest, styled group by group, were danced at different speeds.
    features = np.random.default_rng(3).normal(size=(1, 480, 28)).astype(np.float32)
    features[:, 240:] = features[:, 240:] * 3 + 2
    features = torch.from_numpy(features)
    beats = _beat_flags(480, np.arange(2.0, 480.0, 8.0))
    styles: list[torch.Tensor] = []
    hook = trained.e_std.register_forward_hook(lambda module, inputs, output: styles.append(inputs[0].clone()))
    try:
        trained.generate(features, beats, torch.Generator().manual_seed(0))
        per_song, styles[:] = list(styles), []
        trained.config = replace(trained.config, song_style=False)
        trained.generate(features, beats, torch.Generator().manual_seed(0))
    finally:
        hook.remove()
        trained.config = replace(trained.config, song_style=True)
    assert len(per_song) > 1 and all(torch.equal(s, per_song[0]) for s in per_song)
    assert not all(torch.allclose(s, styles[0]) for s in styles)


def test_a_song_without_two_beats_is_refused_with_a_hint(trained):
    with pytest.raises(DancesynthError, match="fewer than two beats"):
        trained.generate(torch.zeros(1, 60, 28), _beat_flags(60, np.array([30.0])), torch.Generator().manual_seed(0))


def test_real_unit_motion_is_learned_and_still_draws_are_redrawn(trained):
    whole_dances = _batch().poses.flatten(2)
    assert float(trained.unit_motion) == pytest.approx(unit_motion(whole_dances), rel=0.3)
    feature_units = torch.zeros(7, du.UNIT_FRAMES, 28)
    saved_config, saved_motion = trained.config, trained.unit_motion.clone()
    try:
        trained.config = replace(TINY, redraw_tries=1)
        once = trained.dance_units(feature_units, torch.Generator().manual_seed(5))
        trained.config = replace(TINY, redraw_tries=8)
        trained.unit_motion.fill_(1e6)  # unreachable: every group keeps its liveliest of 8 draws
        best = trained.dance_units(feature_units, torch.Generator().manual_seed(5))
        trained.unit_motion.fill_(0.0)  # every first draw passes: nothing is redrawn
        again = trained.dance_units(feature_units, torch.Generator().manual_seed(5))
    finally:
        trained.config = saved_config
        trained.unit_motion.copy_(saved_motion)
    assert best.shape == once.shape == (7, du.UNIT_FRAMES, 25, 2)
    assert torch.equal(once, again)
    first_group = slice(0, TINY.max_units)
    assert unit_motion(best[first_group].flatten(2)) > unit_motion(once[first_group].flatten(2))
    with pytest.raises(DancesynthError, match="redraw"):
        replace(TINY, redraw_tries=0)


def test_the_redraw_floor_rises_for_a_song_danced_slower_than_training(trained):
    feature_units = torch.zeros(7, du.UNIT_FRAMES, 28)
    first_group = slice(0, TINY.max_units)
    saved_config, saved_motion = trained.config, trained.unit_motion.clone()
    try:
        trained.config = replace(TINY, redraw_tries=8)
        trained.unit_motion.fill_(0.0)
        first_draw = trained.dance_units(feature_units, torch.Generator().manual_seed(5))
        # The floor sits just below the first draw's motion: at the training tempo it passes at once.
        trained.unit_motion.fill_(0.9 * unit_motion(first_draw[first_group].flatten(2)) / TINY.redraw_motion)
        same_tempo = trained.dance_units(feature_units, torch.Generator().manual_seed(5))
        half_tempo = trained.dance_units(feature_units, torch.Generator().manual_seed(5), tempo_scale=2.0)
        double_tempo = trained.dance_units(feature_units, torch.Generator().manual_seed(5), tempo_scale=0.5)
    finally:
        trained.config = saved_config
        trained.unit_motion.copy_(saved_motion)
    assert torch.equal(same_tempo[first_group], first_draw[first_group])
    assert torch.equal(double_tempo[first_group], first_draw[first_group])  # played faster: the floor stays
    assert unit_motion(half_tempo[first_group].flatten(2)) > unit_motion(first_draw[first_group].flatten(2))


def test_a_dance_continues_the_same_way_wherever_its_units_have_walked(trained):
    codes = torch.randn(4, TINY.z_mov, generator=torch.Generator().manual_seed(1))
    z_ini = torch.zeros(1, TINY.z_ini)
    with torch.no_grad():
        start = trained.g_uni.initial(z_ini)
        home = start.view(25, 2)[ROOT]
        step = torch.tensor([[4.0, 1.0]])
        walked = shift_root(start.view(1, 1, 25, 2), step).flatten(2)[:, 0]
        here = trained._decode_group(z_ini, start, codes, home)
        there = trained._decode_group(z_ini, walked, codes, home)
        unaware = trained._decode_group(z_ini, walked, codes, None)  # E_ini reading the root too
    expected = shift_root(here.view(4, du.UNIT_FRAMES, 25, 2), step.expand(4, 2)).flatten(2)
    assert torch.allclose(there, expected, atol=1e-5)
    assert not torch.allclose(unaware, expected, atol=1e-3)


def test_steady_energy_keeps_every_group_of_a_long_song_near_the_songs_energy():
    torch.manual_seed(0)
    fresh = Dancing2MusicMethod(TINY).eval()  # before composition: one unit per group, codes from the prior
    feature_units = torch.zeros(24, du.UNIT_FRAMES, 28)
    spread = {}  # band -> fastest over slowest unit's motion
    for band in (0.0, 0.05):
        fresh.config = replace(TINY, redraw_tries=30, steady_energy=band)
        with torch.no_grad():
            units = fresh.dance_units(feature_units, torch.Generator().manual_seed(5))
        motions = [unit_motion(unit[None].flatten(2)) for unit in units]
        spread[band] = max(motions) / min(motions)
    assert spread[0.05] <= np.exp(2 * 0.05) + 1e-6 < 1.5 < spread[0.0]


def test_runs_saved_before_the_redraw_threshold_load_without_redraws(trained):
    state = {k: v for k, v in trained.state_dict().items() if k != "unit_motion"}
    older = Dancing2MusicMethod(TINY)
    older.load_state_dict(state)
    assert float(older.unit_motion) == 0.0


def test_model_before_composition_generates_from_the_prior(trained):
    fresh = Dancing2MusicMethod(TINY).eval()
    assert not fresh.composes and trained.composes
    beats = _beat_flags(60, np.arange(0, 60, 8.0))
    out = fresh.generate(torch.zeros(1, 60, 28), beats, torch.Generator().manual_seed(0))
    assert out.shape == (1, 60, 25, 2)


def test_ablation_without_composition_draws_movements_from_the_prior():
    torch.manual_seed(0)
    model = Dancing2MusicMethod(replace(TINY, composition=False, decomp_epochs=TINY.epochs)).eval()
    beats = _beat_flags(80, np.arange(2, 80, 9.0))
    out = model.generate(torch.zeros(1, 80, 28), beats, torch.Generator().manual_seed(3))
    assert out.shape == (1, 80, 25, 2) and torch.isfinite(out).all()


def test_both_phases_train_through_the_shared_trainer(tiny_stage1_dataset, tmp_path):
    import shutil

    from stage1_pose.generate import generate_from_features, load_pose_model
    from stage1_pose.train import TrainerConfig, train

    data = tmp_path / "data"
    shutil.copytree(tiny_stage1_dataset, data)
    feats = data / "features" / "dancing2music"
    feats.mkdir(parents=True, exist_ok=True)  # another test may have computed them in the shared dataset
    rng = np.random.default_rng(0)
    for clip in (data / "poses").glob("*.npz"):
        np.save(feats / f"{clip.stem}.npy", rng.standard_normal((120, 28)).astype(np.float32))
    overrides = dict(gru_hidden=16, mlp_hidden=16, z_mov=8, z_dan=8, noise_dim=4, min_units=1, max_units=2,
                     window_frames=120, batch_size=2, epochs=2, decomp_epochs=1)
    meta = train("dancing2music", data, tmp_path / "run", overrides=overrides, device="cpu",
                 options=TrainerConfig(preview_every=0))
    assert meta["epoch"] == 2 and min(meta["curriculum"]["phase_steps"]) >= 1
    model = load_pose_model(tmp_path / "run", "cpu")
    dance = generate_from_features(model, rng.standard_normal((75, 28)).astype(np.float32), np.arange(0, 5, 0.5),
                                   seed=1)
    assert dance.keypoints.shape == (75, 25, 3)


def test_relative_movement_codes_ignore_where_a_unit_starts():
    """With relative_movement the movement code depends on the motion only, not on the unit's position."""
    m = Dancing2MusicMethod(replace(TINY, relative_movement=True, motion_scale=20.0)).eval()
    units = torch.from_numpy(np.stack([_dance(32, 8.0, phase) for phase in (0.0, 1.0)])).float()
    shifted = shift_root(units, torch.tensor([[0.3, -0.1], [0.2, 0.1]]))
    with torch.no_grad():
        mu, _ = m.e_mov(units.flatten(2))
        mu_shifted, _ = m.e_mov(shifted.flatten(2))
        decoded = m.g_uni(torch.zeros(2, TINY.z_ini), mu, units.flatten(2)[:, 0])
    np.testing.assert_allclose(mu.numpy(), mu_shifted.numpy(), atol=1e-5)
    # The decoder's displacements are motion_scale times smaller than its raw outputs: a fresh model moves little.
    assert (decoded - decoded[:, :1]).abs().max() < 0.2
