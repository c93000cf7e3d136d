"""Synthetic dances: BODY_25 on the canvas, constant bones, smooth, feet on the floor, varied, on the beat."""

from __future__ import annotations

import numpy as np
import pytest

from dancesynth.core.skeleton import BODY25_LIMBS, JOINT_INDEX
from stage1_pose.data.layout import POSE_FPS
from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_dance import HEIGHT, WIDTH, choreograph, synthesize_dance


def _dance(style: str, seed: int, bpm: float = 100.0, seconds: float = 20.0):
    beats = np.arange(0.3, seconds, 60.0 / bpm)
    frames = int(seconds * POSE_FPS)
    return synthesize_dance(STYLES[style], beats, frames, np.random.default_rng(seed)), beats


@pytest.mark.parametrize("style", sorted(STYLES))
def test_pose_sequence_on_the_canvas(style):
    seq, _ = _dance(style, 0)
    assert seq.keypoints.shape == (300, 25, 3) and seq.fps == POSE_FPS and (seq.width, seq.height) == (WIDTH, HEIGHT)
    assert np.all(seq.confidence == 1)
    assert np.all((seq.xy >= 0) & (seq.xy[..., 0] <= WIDTH)[..., None] & (seq.xy[..., 1] <= HEIGHT)[..., None])


@pytest.mark.parametrize("style", sorted(STYLES))
def test_bone_lengths_are_constant_and_motion_is_smooth(style):
    seq, _ = _dance(style, 1)
    lengths = np.stack([np.linalg.norm(seq.xy[:, a] - seq.xy[:, b], axis=-1) for a, b in BODY25_LIMBS], axis=1)
    assert np.all(lengths.max(0) - lengths.min(0) < 1e-2 * lengths.mean(0) + 1e-3)
    height = lengths[:, 0].mean() / 0.29  # the torso is about 0.29 body heights
    jumps = np.linalg.norm(np.diff(seq.xy, axis=0), axis=-1)
    assert jumps.max() < 0.3 * height
    accel = np.linalg.norm(np.diff(seq.xy, 2, axis=0), axis=-1)
    assert np.percentile(accel, 99) < 0.15 * height


@pytest.mark.parametrize("style", sorted(STYLES))
def test_feet_stay_on_the_floor_except_in_jumps(style):
    seq, _ = _dance(style, 2)
    feet = [JOINT_INDEX[f"{s}{j}"] for s in "RL" for j in ("Ankle", "BigToe", "SmallToe", "Heel")]
    lowest = seq.xy[:, feet, 1].max(axis=1)
    floor = lowest.max()
    assert np.mean(np.abs(lowest - floor) < 0.5) > 0.6  # standing frames touch one floor line
    assert seq.xy[:, :, 1].max() <= floor + 1e-3


def test_dances_of_one_style_differ_and_are_reproducible():
    a, _ = _dance("hiphop", 3)
    b, _ = _dance("hiphop", 4)
    c, _ = _dance("hiphop", 3)
    assert np.array_equal(a.keypoints, c.keypoints)
    rel = lambda s: s.xy - s.xy[:, 8:9]  # noqa: E731 - body shape without position
    assert np.abs(rel(a) - rel(b)).mean() > 5.0


@pytest.mark.parametrize("style", sorted(STYLES))
def test_key_poses_fall_on_beats_but_not_on_all(style):
    beats = np.arange(0.3, 30, 0.6)
    times, poses = choreograph(STYLES[style], beats, np.random.default_rng(0))
    assert times[0] == 0 and np.all(np.isin(times[1:], beats))
    assert len(times) - 1 < len(beats)
    moving = np.abs(np.diff(poses, axis=0)).max(axis=1) > 1e-9
    assert moving.mean() > 0.7
