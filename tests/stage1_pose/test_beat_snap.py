import numpy as np
import pytest
import torch

from dancesynth.core.motion import beats_aligned, joint_speeds, mean_speed, velocity_minimum_beats
from dancesynth.core.skeleton import BODY25_TREE, JOINT_INDEX, NUM_JOINTS, ROOT
from stage1_pose.beat_snap import BeatSnap, accent_times, move_sizes, snap_anchors, snap_to_beats
from stage1_pose.models.kinematics import absolute_positions, forward_kinematics, joint_lengths

FPS = 15.0
BEAT_FRAMES = 8.0  # 112.5 BPM at 15 fps


def swinging_arms(frames: int, stop_offset: float, period: float = BEAT_FRAMES) -> np.ndarray:
    """``[frames, 25, 2]`` model-coordinate poses: a standing body whose arms swing and stop every ``period`` frames,
    ``stop_offset`` frames after each multiple of ``period``."""
    t = np.arange(frames)
    return _arms_at(0.8 * np.cos(np.pi * (t - stop_offset) / period))  # angular speed 0 at t = offset + n * period


def _arms_at(angle: np.ndarray) -> np.ndarray:
    """``[T, 25, 2]`` model-coordinate poses of a standing body whose arms hang at ``[T]`` angles (radians)."""
    raw = np.zeros((len(angle), NUM_JOINTS, 2))
    for _, _parent, child in BODY25_TREE:  # every bone points down, the torso and head up
        raw[:, child] = (0.0, -1.0) if child in (JOINT_INDEX["Neck"], JOINT_INDEX["Nose"]) else (0.2, 1.0)
    for joint in ("RElbow", "RWrist", "LElbow", "LWrist"):
        raw[:, JOINT_INDEX[joint]] = np.stack([np.sin(angle), np.cos(angle)], axis=1)
    raw[:, ROOT] = 0.0
    return forward_kinematics(torch.from_numpy(raw), torch.full((NUM_JOINTS,), 0.25, dtype=torch.float64)).numpy()


def bar_dance(frames: int, big_at: float) -> np.ndarray:
    """Arms that stop on every beat (multiples of ``BEAT_FRAMES``) and make one large move a bar of four beats,
    starting ``big_at`` frames after each multiple of four beats; the three small moves take it back."""
    t = np.arange(frames, dtype=np.float64)
    move = np.floor((t - big_at) / BEAT_FRAMES)
    u = (t - big_at) / BEAT_FRAMES - move  # within each move: 0 at its start, 1 at its end
    big = move % 4 == 0
    start = np.where(big, -0.6, np.where(move % 4 == 1, 0.6, np.where(move % 4 == 2, 0.2, -0.2)))
    eased = (1.0 - np.cos(np.pi * u)) / 2.0  # speed 0 at each stop
    return _arms_at(start + np.where(big, 1.2, -0.4) * eased)


def test_stops_two_frames_late_move_onto_the_beats_keeping_length_bones_and_speed():
    poses = swinging_arms(300, stop_offset=2.0)
    beats = np.arange(0.0, 300, BEAT_FRAMES)
    before = velocity_minimum_beats(absolute_positions(poses), FPS)
    assert beats_aligned(before, beats, 1).mean() < 0.05

    snapped = snap_to_beats(poses, beats, FPS)

    after = velocity_minimum_beats(absolute_positions(snapped), FPS)
    assert snapped.shape == poses.shape and np.isfinite(snapped).all()
    assert beats_aligned(after, beats, 1).mean() >= 0.9
    lengths = joint_lengths(torch.from_numpy(snapped)).numpy()
    np.testing.assert_allclose(np.delete(lengths, ROOT, axis=1), 0.25, atol=1e-6)
    np.testing.assert_allclose(snapped[[0, -1]], poses[[0, -1]], atol=1e-9)
    speed = mean_speed(absolute_positions(snapped), FPS) / mean_speed(absolute_positions(poses), FPS)
    assert 0.95 < speed < 1.05


def test_a_dance_already_on_the_beats_is_left_as_it_is_and_no_beats_change_nothing():
    poses = swinging_arms(200, stop_offset=0.0)
    beats = np.arange(0.0, 200, BEAT_FRAMES)
    np.testing.assert_allclose(snap_to_beats(poses, beats, FPS, BeatSnap(accent=0.0)), poses, atol=1e-3)
    np.testing.assert_array_equal(snap_to_beats(poses, np.zeros(0), FPS), poses)


def test_the_accent_holds_after_each_beat_and_stops_in_the_frame_into_it_keeping_the_beats_and_the_speed():
    poses = swinging_arms(240, stop_offset=0.0)
    beats = np.arange(0.0, 240, BEAT_FRAMES)
    plain = snap_to_beats(poses, beats, FPS, BeatSnap(accent=0.0))
    accented = snap_to_beats(poses, beats, FPS)
    inner = beats[1:-1].astype(int)
    np.testing.assert_allclose(accented[inner], plain[inner], atol=1e-9)  # on the beats: the same poses

    def around_beats(dance):
        """Speed lost in the frame into each beat, and speed over the frame after it, as shares of the beat
        interval's top speed."""
        speed = joint_speeds(absolute_positions(dance), FPS).mean(axis=1)  # [t]: frame t -> t + 1
        top = [speed[b - int(BEAT_FRAMES):b].max() for b in inner]
        return (np.mean([(speed[b - 2] - speed[b - 1]) / m for b, m in zip(inner, top)]),
                np.mean([speed[b] / m for b, m in zip(inner, top)]))

    (lost_plain, after_plain), (lost, after) = around_beats(plain), around_beats(accented)
    assert lost > 1.2 * lost_plain  # 0.54 against 0.37 of the top speed
    assert after < 0.5 * after_plain  # 0.02 against 0.20
    speed = mean_speed(absolute_positions(accented), FPS) / mean_speed(absolute_positions(plain), FPS)
    assert 0.95 < speed < 1.05


def test_accent_times_fix_the_beats_and_the_ends_and_never_run_backwards():
    beats = np.array([3.0, 10.5, 18.0, 26.25])
    times = accent_times(30, beats, 0.5)
    np.testing.assert_allclose(times[:4], np.arange(4))  # before the first beat
    np.testing.assert_allclose(times[27:], np.arange(27, 30))  # after the last
    np.testing.assert_allclose(np.interp(beats, np.arange(30), times), beats, atol=0.5)
    assert times[18] == 18.0 and (np.diff(times) > 0).all()
    with pytest.raises(ValueError, match="accent"):
        BeatSnap(accent=1.5)


def test_anchors_keep_order_use_each_beat_once_and_bound_the_playback_rate():
    rng = np.random.default_rng(0)
    kinematic = np.sort(rng.choice(np.arange(3, 297), 70, replace=False))
    beats = np.arange(0.0, 300, 7.3)
    src, dst = snap_anchors(kinematic, beats, 300, max_shift_frames=3.0, max_rate=1.5)
    assert (src[0], dst[0], src[-1], dst[-1]) == (0, 0, 299, 299)
    rate = np.diff(dst) / np.diff(src)
    assert (np.diff(src) > 0).all() and (np.diff(dst) > 0).all()
    assert ((rate >= 1 / 1.5 - 1e-9) & (rate <= 1.5 + 1e-9)).all()
    inner_src, inner_dst = src[1:-1], dst[1:-1]
    assert np.isin(inner_src, kinematic).all() and np.isin(inner_dst, beats).all()
    assert (np.abs(inner_src - inner_dst) <= 3.0).all()
    assert len(inner_src) >= 30


def test_a_tighter_rate_bound_moves_fewer_beats():
    poses = swinging_arms(300, stop_offset=3.0, period=9.0)
    beats = np.arange(0.0, 300, BEAT_FRAMES)
    kinematic = velocity_minimum_beats(absolute_positions(poses), FPS)
    loose = snap_anchors(kinematic, beats, 300, BeatSnap().max_shift * FPS, 1.5)[0]
    tight = snap_anchors(kinematic, beats, 300, BeatSnap().max_shift * FPS, 1.05)[0]
    assert len(tight) < len(loose)


def test_the_bar_pass_moves_each_large_move_from_the_second_beat_onto_the_downbeat():
    frames = 250  # the last large move (233) reaches its downbeat (224) within the rate bound before the end
    poses = bar_dance(frames, big_at=BEAT_FRAMES)  # the large moves start one beat late
    beats = np.arange(0.0, frames, BEAT_FRAMES)
    downbeats = beats[::4]

    def large_move_starts(dance: np.ndarray) -> np.ndarray:
        xy = absolute_positions(dance)
        kinematic = velocity_minimum_beats(xy, FPS)
        sizes = move_sizes(xy, FPS, kinematic)
        return kinematic[sizes > 0.6 * sizes.max()]

    plain = snap_to_beats(poses, beats, FPS, BeatSnap(bars=False), downbeats)
    barred = snap_to_beats(poses, beats, FPS, BeatSnap(), downbeats)

    assert beats_aligned(large_move_starts(plain), downbeats, 1).mean() == 0.0
    on_bars = beats_aligned(large_move_starts(barred), downbeats, 1)
    assert len(on_bars) >= 5 and on_bars.mean() == 1.0
    assert beats_aligned(velocity_minimum_beats(absolute_positions(barred), FPS), beats, 1).mean() >= 0.9
    np.testing.assert_allclose(barred[[0, -1]], poses[[0, -1]], atol=1e-9)


def test_without_bars_the_downbeats_change_nothing():
    poses = swinging_arms(200, stop_offset=2.0)
    beats = np.arange(0.0, 200, BEAT_FRAMES)
    alone = snap_to_beats(poses, beats, FPS)
    np.testing.assert_array_equal(snap_to_beats(poses, beats, FPS, BeatSnap(bars=False), beats[::4]), alone)


def test_of_two_movement_beats_within_reach_of_one_beat_the_heavier_takes_it():
    kinematic, beat = np.array([10.0, 13.0]), np.array([11.0])  # one frame and two frames from the beat

    def anchored(weights):
        src, dst = snap_anchors(kinematic, beat, 30, max_shift_frames=3.0, max_rate=1.5, weights=weights)
        return src[1:-1].tolist(), dst[1:-1].tolist()

    assert anchored(None) == ([10.0], [11.0])  # equal weights: the smaller shift
    assert anchored(np.array([1.0, 2.0])) == ([13.0], [11.0])  # the heavier, though it moves further
    assert anchored(np.array([2.0, 1.0])) == ([10.0], [11.0])


def test_move_sizes_are_the_path_travelled_until_the_next_movement_beat():
    xy = np.zeros((10, 1, 2))
    xy[:, 0, 0] = [0, 1, 2, 3, 3, 3, 1, 0, 0, 0]
    np.testing.assert_allclose(move_sizes(xy, FPS, np.array([0, 4, 8])), [3.0, 3.0, 0.0])
