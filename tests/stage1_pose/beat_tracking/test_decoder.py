"""The bar-pointer decoder on constructed activations: spikes at known beat times, with noise."""

import mir_eval
import numpy as np
import pytest

from stage1_pose.beat_tracking.decoder import DecoderConfig, beat_lengths, decode

FPS = 50.0


def spikes(beats: np.ndarray, metre: int, seconds: float, seed: int = 0,
           noise: float = 0.05, height: float = 0.7) -> tuple[np.ndarray, np.ndarray]:
    """(beat, downbeat) activations at ``FPS``: uniform noise up to ``noise``, a peak of ``height`` at each beat
    (every ``metre``-th a downbeat) with half of it on the frames either side, as the network's widened targets
    teach it, and random jitter of one frame and of the height."""
    rng = np.random.default_rng(seed)
    frames = int(seconds * FPS)
    beat, down = rng.uniform(0, noise, frames), rng.uniform(0, noise / 2, frames)
    for i, t in enumerate(beats):
        f = int(round(t * FPS)) + int(rng.integers(-1, 2))
        if 1 <= f < frames - 1:
            peak = height * rng.uniform(0.6, 1.0)
            (down if i % metre == 0 else beat)[f - 1:f + 2] = (peak / 2, peak, peak / 2)
    return beat, down


@pytest.mark.parametrize(("bpm", "metre"), [(120, 4), (96, 3), (170, 4), (66, 3)])
def test_beats_and_downbeats_of_noisy_spikes(bpm, metre):
    truth = np.arange(1.0, 39.0, 60.0 / bpm)
    found = decode(*spikes(truth, metre, 40.0), FPS)
    assert found.metre == metre
    assert mir_eval.beat.f_measure(truth, found.beats) >= 0.95
    assert mir_eval.beat.f_measure(truth[::metre], found.downbeats) >= 0.9
    assert found.bpm == pytest.approx(bpm, rel=0.04)


def test_missing_and_spurious_spikes_keep_the_grid():
    truth = np.arange(1.0, 39.0, 0.5)
    beat, down = spikes(truth, 4, 40.0)
    rng = np.random.default_rng(1)
    for t in rng.choice(truth, size=len(truth) // 4, replace=False):
        f = int(round(t * FPS))
        beat[f - 1:f + 2], down[f - 1:f + 2] = 0.01, 0.01
    beat[(np.arange(0.75, 39.0, 2.0) * FPS).astype(int)] = 0.4   # an off-beat accent every other bar
    found = decode(beat, down, FPS)
    assert mir_eval.beat.f_measure(truth, found.beats) >= 0.9


def test_tempo_change_is_followed():
    first = np.arange(1.0, 20.0, 60.0 / 100)
    second = first[-1] + np.cumsum(np.full(40, 60.0 / 130))
    truth = np.concatenate([first, second])
    found = decode(*spikes(truth, 4, truth[-1] + 1.0), FPS)
    assert mir_eval.beat.f_measure(truth, found.beats) >= 0.9


def test_silence_before_and_after_has_no_beats():
    truth = np.arange(5.0, 25.0, 0.5)
    beat, down = spikes(truth, 4, 30.0, noise=0.01)
    found = decode(beat, down, FPS)
    assert found.beats[0] >= 4.9 and found.beats[-1] <= 25.1
    empty = decode(np.zeros(500), np.zeros(500), FPS)
    assert len(empty.beats) == 0 and len(empty.downbeats) == 0


def test_tempo_states_cover_the_range():
    taus = beat_lengths(FPS, DecoderConfig(min_bpm=60, max_bpm=200))
    assert taus[0] == 15 and taus[-1] == 50 and np.all(np.diff(taus) > 0)


@pytest.mark.parametrize("bpm", [80, 90])
def test_a_slow_song_with_marked_off_beats_keeps_its_tempo(bpm):
    """The networks' peaks are two frames wide at 50 fps with next to nothing beside them, and on a slow song with
    busy eighths they mark the off-beats too, at half height: the beats stay at the song's tempo, not double."""
    rng = np.random.default_rng(0)
    beat, down = rng.uniform(0, 0.02, int(40 * FPS)), rng.uniform(0, 0.01, int(40 * FPS))
    truth = np.arange(1.0, 39.0, 60.0 / bpm)
    for i, t in enumerate(truth):
        f, g = int(t * FPS), int((t + 30.0 / bpm) * FPS)
        (down if i % 4 == 0 else beat)[f:f + 2] = 0.6 * rng.uniform(0.8, 1.0)
        beat[g:g + 2] = 0.3 * rng.uniform(0.8, 1.0)
    found = decode(beat, down, FPS)
    assert found.bpm == pytest.approx(bpm, rel=0.04)
    assert mir_eval.beat.f_measure(truth, found.beats) >= 0.95
