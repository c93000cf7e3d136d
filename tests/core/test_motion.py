"""Motion measures: speeds in known units, speed by beat phase, dance distance, chance hit rate, kinematic beats
found at constructed stops and on the music beats of the built-in dances, and physical plausibility (bone-length
error, legs/arms speed ratio, jerk) on constructed dances with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from dancesynth.core.motion import (
    ARM_JOINTS,
    LEG_JOINTS,
    DanceDistance,
    beats_aligned,
    bone_length_errors,
    bone_lengths,
    chance_hit_rate,
    dance_distance,
    joint_speeds,
    kinematic_beats,
    kinematic_offsets,
    legs_arms_speed_ratio,
    mean_jerk,
    mean_speed,
    motion_histogram,
    reference_bone_lengths,
    speed_by_beat_phase,
    upside_down_share,
    velocity_minimum_beats,
)
from dancesynth.core.skeleton import BODY25_LIMBS, JOINT_INDEX, ROOT, normalize
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


def rotating_body(frames: int = 40) -> np.ndarray:
    """``[frames, 25, 2]`` a random body turning rigidly about a point, a quarter turn per second at 15 fps."""
    body = np.random.default_rng(0).uniform(-100, 100, (25, 2))
    angle = 2 * np.pi * 0.25 * np.arange(frames) / 15.0
    rot = np.stack([np.stack([np.cos(angle), -np.sin(angle)], -1), np.stack([np.sin(angle), np.cos(angle)], -1)], -2)
    return np.einsum("tij,kj->tki", rot, body) + np.array([640.0, 360.0])


def test_a_rigidly_turning_body_keeps_every_bone_length():
    xy = rotating_body()
    assert bone_lengths(xy).shape == (40, len(BODY25_LIMBS))
    errors = bone_length_errors(xy, reference_bone_lengths(xy))
    np.testing.assert_allclose(errors, 0.0, atol=1e-12)


def test_a_forearm_stretched_2x_in_half_the_frames():
    real = rotating_body(10)
    xy = real.copy()
    elbow, wrist = JOINT_INDEX["RElbow"], JOINT_INDEX["RWrist"]
    xy[:5, wrist] = xy[:5, elbow] + 2 * (xy[:5, wrist] - xy[:5, elbow])
    forearm = BODY25_LIMBS.index((elbow, wrist))
    # Against the real dancer's body: error 1 in the 5 stretched frames of 1 bone of 24, else 0.
    errors = bone_length_errors(xy, reference_bone_lengths(real))
    assert errors.mean() == pytest.approx(5 / (10 * 24))
    assert np.percentile(errors, 99) == pytest.approx(1.0)  # 5 of 240 values (2 %) are 1
    np.testing.assert_allclose(np.delete(errors, forearm, axis=1), 0.0, atol=1e-12)
    # Against its own median (1.5x the forearm): every frame of that bone is off by 1/3.
    own = bone_length_errors(xy, reference_bone_lengths(xy))
    np.testing.assert_allclose(own[:, forearm], 1 / 3)
    assert own.mean() == pytest.approx(1 / 3 / 24)


def test_a_bone_missing_from_the_reference_is_left_out():
    xy = rotating_body(5)
    ref = reference_bone_lengths(xy)
    ref[0] = 0.0
    errors = bone_length_errors(xy, ref)
    assert np.isnan(errors[:, 0]).all() and np.isfinite(errors[:, 1:]).all()


def test_a_joint_moving_as_t_cubed_has_jerk_6():
    t = np.arange(30) / 15.0
    xy = np.stack([t ** 3, np.zeros_like(t)], -1)[:, None, :]  # px, t in seconds
    assert mean_jerk(xy, 15.0) == pytest.approx(6.0)
    assert mean_jerk(np.full((10, 4, 2), 7.0), 15.0) == 0.0  # standing still
    assert np.isnan(mean_jerk(rotating_body(3), 15.0))  # too short for a third derivative


def test_legs_arms_speed_ratio():
    t = np.arange(20)[:, None]
    xy = np.zeros((20, 25, 2))
    xy[:, list(ARM_JOINTS), 0] = 2.0 * t
    assert legs_arms_speed_ratio(xy, 15.0) == 0.0  # legs still
    xy[:, list(LEG_JOINTS), 1] = 1.0 * t
    assert legs_arms_speed_ratio(xy, 15.0) == pytest.approx(0.5)
    assert np.isnan(legs_arms_speed_ratio(np.zeros((20, 25, 2)), 15.0))  # arms still: undefined


def test_upside_down_share_counts_frames_with_the_neck_below_the_hip():
    xy = np.zeros((8, 25, 2))
    xy[:, JOINT_INDEX["Neck"], 1] = -1.0  # neck above the hip (image y grows downwards)
    assert upside_down_share(xy) == 0.0
    xy[:2, JOINT_INDEX["Neck"], 1] = 1.0
    assert upside_down_share(xy) == pytest.approx(0.25)
    assert np.isnan(upside_down_share(np.zeros((0, 25, 2))))
