"""Kinematic beats: found at constructed stops, and on the music beats of the built-in dances."""

from __future__ import annotations

import numpy as np
import pytest

from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_dance import FPS, synthesize_dance
from dancesynth.core.motion import (kinematic_beats, kinematic_offsets, motion_histogram,
                                         velocity_minimum_beats)
from dancesynth.core.skeleton import normalize

STOPS = (20, 45, 70)


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
    assert len(minima) == len(STOPS) and np.all(np.abs(minima - (np.array(STOPS) + 1)) <= 1)  # middle of each still span


def test_still_and_tiny_inputs_have_no_beats():
    still = np.zeros((30, 25, 2))
    assert len(kinematic_beats(still, 15)) == 0 and len(velocity_minimum_beats(still, 15)) == 0
    assert len(kinematic_beats(still[:2], 15)) == 0
    with pytest.raises(ValueError):
        kinematic_offsets(np.zeros((10, 25)), 15)


def _hit_rate(found: np.ndarray, beat_frames: np.ndarray, tolerance: int = 1) -> float:
    return float(np.mean(np.abs(found[:, None] - beat_frames[None]).min(1) <= tolerance))


@pytest.mark.parametrize("style", sorted(STYLES))
def test_builtin_dances_hit_music_beats_far_above_chance(style):
    rng = np.random.default_rng(0)
    bpm = float(np.mean(STYLES[style].bpm_range))
    beats = np.arange(0.37, 40.0, 60.0 / bpm)
    frames = int(40 * FPS)
    beat_frames = np.round(beats * FPS).astype(int)
    for detector in (lambda xy: kinematic_beats(xy, FPS), lambda xy: velocity_minimum_beats(xy, FPS)):
        rates, chances = [], []
        for seed in range(3):
            xy = normalize(synthesize_dance(STYLES[style], beats, frames, np.random.default_rng(seed)))[0]
            found = detector(xy)
            rates.append(_hit_rate(found, beat_frames))
            chances.append(np.mean([_hit_rate(rng.integers(0, frames, len(found)), beat_frames) for _ in range(50)]))
        assert np.mean(rates) > np.mean(chances) + 0.2, (rates, chances)
