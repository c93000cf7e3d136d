import numpy as np
import pytest

from stage1_pose import metrics


def test_fid_of_a_set_against_itself_is_zero_and_grows_with_a_shift():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(400, 8))
    assert metrics.frechet_distance(a, a) == pytest.approx(0.0, abs=1e-6)
    small = metrics.frechet_distance(a, a + 0.5)
    large = metrics.frechet_distance(a, a + 2.0)
    # A pure mean shift d adds exactly ||d||^2 = 8 d^2.
    assert small == pytest.approx(8 * 0.25, rel=1e-6)
    assert large == pytest.approx(8 * 4.0, rel=1e-6)


def test_fid_is_finite_with_fewer_samples_than_dimensions():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(10, 50)), rng.normal(size=(12, 50)) + 1.0
    value = metrics.frechet_distance(a, b)
    assert np.isfinite(value) and value > 0


def test_fid_matches_closed_form_for_scaled_gaussians():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(20000, 2))
    # N(0, I) vs N(0, 4I): tr(I + 4I - 2*2I) = 2 per dimension -> 2 * (1 + 4 - 4) = 2.
    assert metrics.frechet_distance(a, 2 * a) == pytest.approx(2.0, rel=0.05)


def test_beats_exactly_on_music_beats_give_hit_rate_one_and_full_coverage():
    music_frames = np.arange(10, 300, 8)
    assert metrics.beat_hit_rate(music_frames, music_frames) == 1.0
    assert metrics.beat_coverage(music_frames, music_frames) == 1.0
    # Half the kinematic beats off by 4 frames (outside +-2) -> hit rate 0.5.
    kin = np.concatenate([music_frames[::2], music_frames[1::2] + 4])
    assert metrics.beat_hit_rate(kin, music_frames) == pytest.approx(len(music_frames[::2]) / len(kin))


def test_no_kinematic_beats_give_zero_coverage_and_undefined_hit_rate():
    music = np.arange(0, 100, 7)
    assert metrics.beat_coverage(np.array([]), music) == 0.0
    assert np.isnan(metrics.beat_hit_rate(np.array([]), music))
    assert metrics.beat_align_score(music / 15.0, np.array([])) == 0.0


def test_beat_align_score_is_one_for_exact_alignment_and_decays_with_offset():
    music = np.arange(0.5, 20, 0.5)
    assert metrics.beat_align_score(music, music) == pytest.approx(1.0)
    off = metrics.beat_align_score(music, music + 0.05, sigma_seconds=0.05)
    assert off == pytest.approx(np.exp(-0.5), rel=1e-6)


def test_multimodality_of_a_deterministic_model_is_zero():
    rng = np.random.default_rng(3)
    per_song = rng.normal(size=(6, 1, 16))
    assert metrics.multimodality(np.repeat(per_song, 4, axis=1)) == 0.0
    assert metrics.multimodality(per_song + rng.normal(size=(6, 4, 16))) > 0.5


def test_diversity_is_the_mean_pairwise_distance():
    f = np.array([[0.0, 0.0], [3.0, 4.0], [0.0, 0.0]])
    # pairs: (0,1)=5, (0,2)=0, (1,2)=5
    assert metrics.diversity(f) == pytest.approx(10 / 3)
    assert metrics.diversity(np.zeros((5, 3))) == 0.0


def test_style_accuracy():
    assert metrics.style_accuracy(np.array([0, 1, 2, 2]), np.array([0, 1, 1, 2])) == 0.75
    with pytest.raises(ValueError):
        metrics.style_accuracy(np.array([0]), np.array([0, 1]))


def test_fid_over_time_rises_for_a_drifting_set():
    rng = np.random.default_rng(4)
    ref = rng.normal(size=(300, 4))
    windows = np.stack([rng.normal(size=(300, 4)) + 0.5 * w for w in range(5)], axis=1)
    curve = metrics.fid_over_time(windows, ref)
    assert curve.shape == (5,)
    assert np.all(np.diff(curve) > 0)


def test_cross_modal_distance_is_zero_when_the_generated_dance_is_the_neighbours_dance():
    train_music = np.array([[0.0], [10.0], [20.0]])
    train_dance = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    music = np.array([[9.0], [19.0]])
    assert metrics.cross_modal_distance(train_dance[[1, 2]], music, train_music, train_dance) == 0.0
    assert metrics.cross_modal_distance(train_dance[[0, 0]], music, train_music, train_dance) == pytest.approx(
        (np.sqrt(2) + 1) / 2)
