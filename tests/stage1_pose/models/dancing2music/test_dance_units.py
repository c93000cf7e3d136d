import numpy as np
import pytest

from dancesynth.core.errors import DancesynthError
from dancesynth.core.motion import kinematic_beats
from stage1_pose.models.dancing2music import dance_units as du


def _events(num_frames: int, frames: np.ndarray) -> np.ndarray:
    """A 1-joint signal that is 1 at the given (integer) frames and 0 elsewhere, ``[T, 1]``."""
    x = np.zeros((num_frames, 1), np.float32)
    x[np.asarray(frames, int), 0] = 1.0
    return x


def test_unit_normalisation_puts_beats_at_fixed_frames():
    beats = np.array([3, 10, 19, 25, 34], float)  # uneven intervals
    unit = du.cut_units(_events(40, beats), beats[None])[0]
    assert unit.shape == (du.UNIT_FRAMES, 1)
    assert du.BEAT_POSITIONS == (0, 8, 16, 24)
    np.testing.assert_allclose(unit[list(du.BEAT_POSITIONS), 0], 1.0)
    others = np.setdiff1d(np.arange(du.UNIT_FRAMES), du.BEAT_POSITIONS)
    assert unit[others, 0].max() < 1.0


def test_unit_positions_are_piecewise_linear_between_beats():
    pos = du.unit_positions(np.array([0, 8, 24, 28, 36], float))
    np.testing.assert_allclose(pos[:9], np.arange(9))
    np.testing.assert_allclose(pos[8:17], np.linspace(8, 24, 9)[:9])
    with pytest.raises(ValueError):
        du.unit_positions(np.arange(4.0))


def test_unit_runs_chain_units_and_break_at_bad_gaps():
    beats = np.concatenate([np.arange(0, 70, 7.0), [100.0], 100 + np.arange(1, 6) * 6.0])
    runs = du.unit_runs(beats, min_gap=3, max_gap=15)
    # 10 beats before the 30-frame pause -> 2 units; 6 beats after it -> 1 unit.
    assert [len(r) for r in runs] == [2, 1]
    np.testing.assert_array_equal(runs[0][0, -1], runs[0][1, 0])
    assert runs[1][0, 0] == 100.0
    assert du.unit_runs(np.arange(4.0), 0, 10) == []


def test_warper_aligns_unit_beats_to_given_beat_times():
    fps, num_frames = 15.0, 150
    music_beats = np.arange(0.4, 10.0, 0.55) * fps  # fractional frames, 109 BPM
    grid = du.beat_grid(music_beats, num_frames)
    n = du.units_needed(grid)
    units = np.zeros((n, du.UNIT_FRAMES, 1), np.float32)
    units[:, list(du.BEAT_POSITIONS)] = 1.0
    out = du.warp_units(units, grid, num_frames)
    assert out.shape == (num_frames, 1)
    # Each music beat's nearest output frame shows (close to) a unit beat; halfway between beats shows none.
    for b in music_beats[music_beats < num_frames - 1]:
        assert out[int(round(b)), 0] > 0.45
    mids = (music_beats[:-1] + music_beats[1:]) / 2
    assert all(out[int(round(m)), 0] == 0.0 for m in mids if m < num_frames - 1)


def test_aligned_anchors_sit_on_the_units_kinematic_beats():
    # Beats 2 frames late in every interval, plus one extra beat in the middle of interval 5.
    kinematic = np.sort(np.concatenate([np.arange(10) * 8.0 + 2, [46.0]]))
    anchors = du.align_beats(kinematic, 10, max_stretch=2.0)
    assert anchors.shape == (10,) and np.all(np.diff(anchors) > 0)
    # Every beat the anchors span is an anchor or within the margin of one: none falls between two music beats.
    spanned = kinematic[(kinematic >= anchors[0]) & (kinematic <= anchors[-1])]
    assert len(spanned) >= 8
    assert np.abs(spanned[:, None] - anchors[None]).min(axis=1).max() <= 1.5
    assert np.all(np.diff(anchors) >= 4) and np.all(np.diff(anchors) <= 16)
    np.testing.assert_array_equal(du.align_beats(kinematic, 10, max_stretch=1.0), np.arange(10) * 8.0)
    np.testing.assert_array_equal(du.align_beats(np.zeros(0), 4, max_stretch=2.0), np.arange(4) * 8.0)
    # A tight stretch limit keeps the tempo even although the extra beat stays inside an interval.
    tight = du.align_beats(kinematic, 10, max_stretch=1.1)
    assert np.all(np.abs(np.diff(tight) - 8) <= 8 * 0.1 + 1e-9)
    with pytest.raises(ValueError):
        du.align_beats(kinematic, 10, max_stretch=0.5)


def test_warper_lands_unit_beats_at_given_positions_on_the_grid():
    grid = np.arange(0.0, 100.0, 10.0)
    units = np.arange(3 * du.UNIT_FRAMES, dtype=np.float32).reshape(3, du.UNIT_FRAMES, 1)  # value = position
    unit_beats = np.arange(len(grid)) * 8.0 + np.array([0, 2, -1, 3, 0, 1, 0, -2, 2, 0])
    out = du.warp_units(units, grid, 91, unit_beats)
    np.testing.assert_allclose(out[grid.astype(int), 0], unit_beats, atol=1e-4)
    with pytest.raises(ValueError, match="increasing"):
        du.warp_units(units, grid, 91, unit_beats[::-1])


def test_accent_makes_steady_motion_decelerate_on_the_beats():
    fps, num_frames = 15.0, 150
    music_beats = np.arange(4.0, 150.0, 9.0)
    grid = du.beat_grid(music_beats, num_frames)
    n = du.units_needed(grid)
    # One joint walking right at constant speed: no kinematic beats of its own.
    walk = np.zeros((n, du.UNIT_FRAMES, 1, 2), np.float32)
    walk[..., 0, 0] = np.arange(n * du.UNIT_FRAMES, dtype=np.float32).reshape(n, -1) * 0.05
    plain = du.warp_units(walk, grid, num_frames)
    accented = du.warp_units(walk, grid, num_frames, accent=0.5)
    on_beats = np.round(grid[(grid >= 0) & (grid < num_frames)]).astype(int)
    np.testing.assert_allclose(accented[on_beats], plain[on_beats], atol=1e-3)
    beats = kinematic_beats(accented, fps)
    assert len(beats) >= len(music_beats) - 2
    assert np.abs(beats[:, None] - music_beats[None]).min(axis=1).max() <= 1.0
    with pytest.raises(ValueError, match="accent"):
        du.warp_units(walk, grid, num_frames, accent=1.0)


def test_smooth_sampling_is_exact_on_frames_and_on_straight_lines():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(9, 3, 2))
    np.testing.assert_allclose(du.sample_frames_smooth(x, np.arange(9.0)), x)
    line = np.linspace(0, 4, 9)[:, None] * np.array([[1.0, -2.0]])
    pos = np.array([-1.0, 0.3, 2.5, 5.75, 7.9, 12.0])
    np.testing.assert_allclose(du.sample_frames_smooth(line, pos)[1:4], du.sample_frames(line, pos)[1:4])
    np.testing.assert_allclose(du.sample_frames_smooth(line, pos)[[0, -1]], line[[0, -1]])


def test_beat_grid_covers_song_and_strides():
    beats = np.array([10.0, 17.5, 25.0, 32.5, 40.0])
    grid = du.beat_grid(beats, 60)
    assert grid[0] <= 0 and grid[-1] >= 59
    np.testing.assert_allclose(np.diff(grid), 7.5)
    assert du.beat_stride(beats, 15.0) == 2
    np.testing.assert_allclose(np.diff(du.beat_grid(beats, 60, stride=2)), 15.0)
    # A dancer whose kinematic beats come twice per music beat dances on the half beats, music beats included.
    assert du.beat_stride(beats, 3.5) == 0.5
    # The stride nearest in ratio: 1.45x off is nearer 2x than 1x (the split is sqrt(2), not 1.5).
    assert du.beat_stride(beats, 7.5 * 1.45) == 2 and du.beat_stride(beats, 7.5 * 1.4) == 1
    assert du.beat_stride(beats, 7.5 / 1.45) == 0.5 and du.beat_stride(beats, 7.5 / 1.4) == 1
    assert du.beat_stride(beats, 7.5 * 2.5) == 3  # 2.5 > sqrt(2 * 3)
    half = du.beat_grid(beats, 60, stride=0.5)
    np.testing.assert_allclose(np.diff(half), 3.75)
    assert set(beats) <= set(half) and half[0] <= 0 and half[-1] >= 59
    with pytest.raises(DancesynthError, match="fewer than two beats"):
        du.beat_grid(np.array([3.0]), 60)
    with pytest.raises(ValueError):
        du.warp_units(np.zeros((1, du.UNIT_FRAMES, 1)), grid, 60)


def test_sample_frames_interpolates_and_clamps():
    x = np.arange(5, dtype=np.float32)[:, None]
    np.testing.assert_allclose(du.sample_frames(x, np.array([-1.0, 0.5, 3.25, 9.0]))[:, 0], [0, 0.5, 3.25, 4])
