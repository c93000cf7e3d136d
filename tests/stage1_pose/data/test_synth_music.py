"""Synthetic songs: exact beats a beat tracker finds, tempo in the style's range, no clipping, variety."""

from __future__ import annotations

import mir_eval
import numpy as np
import pytest

from stage1_pose.beats import beat_times
from stage1_pose.data.layout import SAMPLE_RATE
from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_music import BEATS_PER_BAR, synthesize_song


@pytest.mark.parametrize("style", sorted(STYLES))
def test_beat_tracker_finds_the_beats(style):
    scores = []
    for seed in range(2):
        song = synthesize_song(STYLES[style], 15.0, np.random.default_rng(seed))
        scores.append(mir_eval.beat.f_measure(song.beats, beat_times(song.samples, song.sample_rate), 0.07))
    assert np.mean(scores) >= 0.9, scores


@pytest.mark.parametrize("style", sorted(STYLES))
def test_song_structure(style):
    s = STYLES[style]
    song = synthesize_song(s, 8.0, np.random.default_rng(1))
    assert song.samples.shape == (8 * SAMPLE_RATE,) and song.samples.dtype == np.float32
    assert song.sample_rate == SAMPLE_RATE
    assert 0.5 < np.abs(song.samples).max() < 0.95
    assert s.bpm_range[0] <= song.tempo <= s.bpm_range[1]
    assert np.allclose(np.diff(song.beats), 60.0 / song.tempo)
    assert 0 < song.beats[0] < 0.6 and song.beats[-1] < 8.0
    assert np.array_equal(song.downbeats, song.beats[::BEATS_PER_BAR])


def test_songs_are_deterministic_per_seed_and_differ_between_seeds():
    a = synthesize_song(STYLES["pop"], 4.0, np.random.default_rng(5))
    b = synthesize_song(STYLES["pop"], 4.0, np.random.default_rng(5))
    c = synthesize_song(STYLES["pop"], 4.0, np.random.default_rng(6))
    assert np.array_equal(a.samples, b.samples) and np.array_equal(a.beats, b.beats)
    assert not np.allclose(a.samples, c.samples, atol=1e-2)
