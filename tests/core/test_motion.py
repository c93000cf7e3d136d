"""Motion measures: speeds in known units, speed by beat phase, dance distance, chance hit rate, and kinematic beats
found at constructed stops and on the music beats of the built-in dances."""

from __future__ import annotations

import numpy as np
import pytest

from dancesynth.core.motion import (
    DanceDistance,
    beats_aligned,
    chance_hit_rate,
    dance_distance,
    joint_speeds,
    kinematic_beats,
    kinematic_offsets,
    mean_speed,
    motion_histogram,
    speed_by_beat_phase,
    velocity_minimum_beats,
)
from dancesynth.core.skeleton import ROOT, normalize
from stage1_pose.data.layout import POSE_FPS
from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_dance import synthesize_dance

STOPS = (20, 45, 70)


def test_a_joint_moving_3_4_px_per_frame_at_15_fps_moves_75_px_per_second():
    t = np.arange(31)[:, None, None]
    xy = np.concatenate([np.concatenate([3.0 * t, 4.0 * t], -1), np.zeros((31, 1, 2))], axis=1)  # joint 1 stands
    speeds = joint_speeds(xy, fps=15.0)
    assert speeds.shape == (30, 2)
    np.testing.assert_allclose(speeds[:, 0], 75.0)
    np.testing.assert_allclose(speeds[:, 1], 0.0)
    assert mean_speed(xy, 15.0) == pytest.approx(37.5)
    assert mean_speed(xy, 15.0, unit_length=25.0) == pytest.approx(1.5)  # torso of 25 px: 1.5 torso lengths/s
    assert mean_speed(xy[:1], 15.0) == 0.0


def test_a_dance_that_stops_on_every_beat_is_slowest_in_the_first_tenth_of_each_beat_interval():
    # Beats every 10 frames; within each interval the joint steps 0, 1, ..., 9 px: the step from frame t to t + 1
    # lies at phase (t + 0.5) / 10, so tenth i of every interval holds exactly the i-px step.
    steps = np.tile(np.arange(10.0), 6)
    x = np.concatenate([[0.0], np.cumsum(steps)])
    xy = np.stack([x, np.zeros_like(x)], -1)[:, None]
    profile = speed_by_beat_phase(xy, np.arange(0, 61, 10), fps=15.0)
    np.testing.assert_allclose(profile, np.arange(10) * 15.0)
    # Without two beats inside the dance no interval is covered.
    assert np.isnan(speed_by_beat_phase(xy, np.array([5.0]), fps=15.0)).all()


def test_dance_distance_splits_the_body_from_where_the_dancer_stands():
    a = np.random.default_rng(0).uniform(0, 100, (20, 25, 2))
    assert dance_distance(a, a + (3.0, 4.0)) == pytest.approx(DanceDistance(5.0, 0.0, 5.0))
    raised_arms = a.copy()
    raised_arms[:, [4, 7]] += (0.0, 24.0)  # both wrists 24 px lower, the MidHip where it was
    gap = dance_distance(a, raised_arms[:10])  # the common 10 frames
    assert gap.root == 0.0 and gap.body == pytest.approx(2 * 24.0 / 25) and gap.joints == gap.body
    assert ROOT not in (4, 7)


def test_beats_on_the_grid_hit_more_often_than_the_same_beats_shifted_at_random():
    grid = np.arange(0, 300, 15.0)  # one music beat a second at 15 fps
    on_grid = grid[::2].astype(np.int64)
    rng = np.random.default_rng(0)
    assert beats_aligned(on_grid, grid).all()
    chance = chance_hit_rate(on_grid, grid, 300, rng)
    # +-2 frames of 15: 5 of 15 random offsets land a beat within tolerance.
    assert 0.0 < chance < 1.0 and chance == pytest.approx(5 / 15, abs=0.05)
    scattered = np.sort(rng.choice(300, 40, replace=False))
    assert 0.0 < chance_hit_rate(scattered, grid, 300, rng) < 1.0
    assert np.isnan(chance_hit_rate(np.array([], np.int64), grid, 300, rng))


def _stop_and_go(frames: int = 90) -> np.ndarray:
    """Two joints moving sideways at constant speed; at each of STOPS they have stopped (no motion into that
    frame) and stand still for 5 frames, then move back the other way."""
    velocity = np.full(frames, 10.0)
    sign = 1.0
    for stop in STOPS:
        velocity[stop:stop + 5] = 0.0
        sign = -sign
        velocity[stop + 5:] = sign * 10.0
    x = np.concatenate([[0.0], np.cumsum(velocity[1:])])
    return np.stack([np.stack([x, np.zeros(frames)], -1), np.stack([x, np.full(frames, 50.0)], -1)], axis=1)


def test_motion_histogram_bins_by_direction():
    xy = _stop_and_go()
    hist = motion_histogram(xy, fps=10.0, bins=4)
    assert hist.shape == (90, 4) and np.all(hist[0] == 0)
    assert np.allclose(hist[1:20].sum(1), 2 * 10 * 10.0)  # two joints, 10 px per frame, 10 fps
    assert np.count_nonzero(hist[1:20].sum(0)) == 1  # all motion in one direction sector


def test_offsets_and_beats_at_constructed_stops():
    xy = _stop_and_go()
    strength = kinematic_offsets(xy, fps=10.0)
    assert strength.shape == (90,) and np.all(strength >= 0)
    beats = kinematic_beats(xy, fps=10.0)
    assert beats.tolist() == list(STOPS)  # Eq. 2: the first frame whose incoming motion is gone
    minima = velocity_minimum_beats(xy, fps=10.0, smooth_sigma=0.1)
    # The middle of each still span.
    assert len(minima) == len(STOPS) and np.all(np.abs(minima - (np.array(STOPS) + 1)) <= 1)


def test_still_and_tiny_inputs_have_no_beats():
    still = np.zeros((30, 25, 2))
    assert len(kinematic_beats(still, 15)) == 0 and len(velocity_minimum_beats(still, 15)) == 0
    assert len(kinematic_beats(still[:2], 15)) == 0
    with pytest.raises(ValueError):
        kinematic_offsets(np.zeros((10, 25)), 15)


@pytest.mark.parametrize("style", sorted(STYLES))
def test_builtin_dances_hit_music_beats_far_above_chance(style):
    rng = np.random.default_rng(0)
    bpm = float(np.mean(STYLES[style].bpm_range))
    beats = np.arange(0.37, 40.0, 60.0 / bpm)
    frames = int(40 * POSE_FPS)
    beat_frames = np.round(beats * POSE_FPS).astype(int)
    for detector in (lambda xy: kinematic_beats(xy, POSE_FPS), lambda xy: velocity_minimum_beats(xy, POSE_FPS)):
        rates, chances = [], []
        for seed in range(3):
            xy = normalize(synthesize_dance(STYLES[style], beats, frames, np.random.default_rng(seed)))[0]
            found = detector(xy)
            rates.append(beats_aligned(found, beat_frames, tolerance_frames=1).mean())
            chances.append(chance_hit_rate(found, beat_frames, frames, rng, shifts=50, tolerance_frames=1))
        assert np.mean(rates) > np.mean(chances) + 0.2, (rates, chances)
