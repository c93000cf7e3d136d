"""Synthetic songs in a style: drums, bass, chords and melody at an exact tempo, with their beat times.

Every instrument is a short note waveform rendered with numpy and added into the mix at its onset sample,
so a one-minute song takes well under a second. Low-frequency energy (kick, bass attacks) falls only on
beats, as in most dance music, so onset-based beat trackers find the true beat rather than a double tempo.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from stage1_pose.data.layout import SAMPLE_RATE
from stage1_pose.data.styles import Style

BEATS_PER_BAR = 4
# Peak level of the finished mix (full scale = 1), headroom against clipping after any resampling.
PEAK = 0.89
MAJOR = (0, 2, 4, 5, 7, 9, 11)
MINOR = (0, 2, 3, 5, 7, 8, 10)
# Chord progressions as scale degrees (0 = tonic), one chord per ``Style.chord_beats``.
PROGRESSIONS = ((0, 4, 5, 3), (0, 5, 3, 4), (0, 3, 4, 4), (5, 3, 0, 4), (0, 3, 5, 4), (0, 4, 3, 4))


@dataclass
class Song:
    """A synthetic song.

    Attributes:
        samples: mono float32 ``[N]`` in [-1, 1] at ``sample_rate`` Hz.
        sample_rate: Hz.
        beats: ``[B]`` float64 beat times in seconds (the exact times the kick and bass notes start).
        downbeats: float64 times in seconds of the first beat of every bar (4/4).
        tempo: beats per minute.
        key: MIDI note number of the tonic (bass register); ``minor`` says the mode.
        minor: whether the song is in a minor key.
    """

    samples: np.ndarray
    sample_rate: int
    beats: np.ndarray
    downbeats: np.ndarray
    tempo: float
    key: int
    minor: bool


def _hz(midi: np.ndarray | float) -> np.ndarray:
    return 440.0 * 2.0 ** ((np.asarray(midi, np.float64) - 69) / 12)


def _lowpass(x: np.ndarray, cutoff_hz: float) -> np.ndarray:
    """One-pole low-pass filter."""
    a = np.exp(-2 * np.pi * cutoff_hz / SAMPLE_RATE)
    return lfilter([1 - a], [1, -a], x)


def _saw(phase: np.ndarray) -> np.ndarray:
    return 2.0 * (phase % 1.0) - 1.0


class _Mixer:
    """A mono bus that notes are added into at sample offsets (notes running past the end are cut)."""

    def __init__(self, n: int) -> None:
        self.out = np.zeros(n, np.float64)

    def add(self, start_s: float, wave: np.ndarray, gain: float = 1.0) -> None:
        start = int(round(start_s * SAMPLE_RATE))
        stop = min(len(self.out), start + len(wave))
        if start < stop:
            self.out[start:stop] += gain * wave[:stop - start]


def _t(seconds: float) -> np.ndarray:
    return np.arange(int(seconds * SAMPLE_RATE)) / SAMPLE_RATE


def _kick(rng: np.random.Generator) -> np.ndarray:
    t = _t(0.35)
    freq = 45 + 110 * np.exp(-t / 0.03)
    phase = 2 * np.pi * np.cumsum(freq) / SAMPLE_RATE
    click = rng.standard_normal(len(t)) * np.exp(-t / 0.003) * 0.3
    return np.sin(phase) * np.exp(-t / 0.12) + click


def _snare(rng: np.random.Generator, clap: bool) -> np.ndarray:
    t = _t(0.25)
    noise = np.diff(rng.standard_normal(len(t) + 1))  # first difference: tilts the noise towards high frequencies
    if clap:  # three quick bursts, as hands clapping together
        env = sum(np.exp(-np.maximum(t - d, 0) / 0.012) * (t >= d) for d in (0.0, 0.011, 0.022))
        return 0.5 * noise * env
    return 0.45 * noise * np.exp(-t / 0.06) + 0.5 * np.sin(2 * np.pi * 200 * t) * np.exp(-t / 0.04)


def _hihat(rng: np.random.Generator, open_hat: bool) -> np.ndarray:
    t = _t(0.2 if open_hat else 0.06)
    noise = np.diff(np.diff(rng.standard_normal(len(t) + 2)))
    return 0.12 * noise * np.exp(-t / (0.06 if open_hat else 0.012))


def _bass_note(midi: float, seconds: float, kind: str) -> np.ndarray:
    t = _t(seconds)
    f = _hz(midi)
    if kind == "808":
        y = np.tanh(1.5 * np.sin(2 * np.pi * f * t)) * np.exp(-t / 0.5)
    elif kind == "synth":
        y = _lowpass(_saw(f * t), 400) * 1.6 * np.exp(-t / 0.3)
    else:  # plucked string: bright attack decaying to a sine
        y = (np.sin(2 * np.pi * f * t) + 0.4 * np.sin(4 * np.pi * f * t) * np.exp(-t / 0.05)) * np.exp(-t / 0.4)
    attack = np.minimum(1.0, t / 0.004)
    release = np.minimum(1.0, (seconds - t) / 0.02)
    return y * attack * release


def _chord(midis: np.ndarray, seconds: float, kind: str, rng: np.random.Generator) -> np.ndarray:
    t = _t(seconds)
    y = np.zeros(len(t))
    for m in midis:
        f = _hz(m)
        if kind == "strings":
            vib = 1 + 0.004 * np.sin(2 * np.pi * 5.5 * t + rng.uniform(0, 2 * np.pi))
            y += sum(_saw(f * d * t * vib + rng.uniform()) for d in (0.997, 1.003))
        elif kind == "keys":
            y += (np.sin(2 * np.pi * f * t) + 0.3 * np.sin(4 * np.pi * f * t)) * np.exp(-t / 0.8)
        else:
            y += _saw(f * t) * np.exp(-t / 0.15)
    if kind == "strings":
        y = _lowpass(y, 1500) * np.minimum(1.0, t / 0.35)
    release = np.minimum(1.0, (seconds - t) / 0.05)
    return 0.12 * y * release


def _lead(midi: float, seconds: float, kind: str) -> np.ndarray:
    t = _t(seconds)
    f = _hz(midi)
    if kind == "flute":
        ph = 2 * np.pi * f * t + 0.15 * np.sin(2 * np.pi * 5 * t)
        y = (np.sin(ph) + 0.2 * np.sin(2 * ph)) * np.minimum(1.0, t / 0.08)
    elif kind == "bell":
        y = (np.sin(2 * np.pi * f * t) + 0.5 * np.sin(2 * np.pi * 2.76 * f * t) * np.exp(-t / 0.1)) * np.exp(-t / 0.6)
    else:
        y = _lowpass(np.sign(np.sin(2 * np.pi * f * t)), 3000) * np.exp(-t / 0.4)
    release = np.minimum(1.0, (seconds - t) / 0.03)
    return 0.18 * y * release


def synthesize_song(style: Style, seconds: float, rng: np.random.Generator) -> Song:
    """Render a ``seconds``-long song in ``style`` with random tempo, key, progression, melody and drum variations.

    Beats start a fraction of a second in and run to the end; the returned beat times are exactly where the
    kick and bass notes start. The mix is scaled so its peak is :data:`PEAK`.
    """
    n = int(round(seconds * SAMPLE_RATE))
    tempo = float(rng.uniform(*style.bpm_range))
    period = 60.0 / tempo
    first = float(rng.uniform(0.1, 0.5))
    beats = np.arange(first, seconds - 0.05, period)
    minor = bool(rng.random() < style.minor_probability)
    scale = np.array(MINOR if minor else MAJOR)
    key = int(rng.integers(36, 48))
    progression = PROGRESSIONS[rng.integers(len(PROGRESSIONS))]
    mix = _Mixer(n)
    # A song repeats its chords and pitches, so each distinct note is rendered once.
    notes: dict[tuple, np.ndarray] = {}

    def note(key: tuple, render: Callable[[], np.ndarray]) -> np.ndarray:
        if key not in notes:
            notes[key] = render()
        return notes[key]

    kick = _kick(rng)
    open_hat_every = int(rng.choice([0, 2, 4]))
    clap = bool(rng.random() < 0.5)
    for i, b in enumerate(beats):
        pos = i % BEATS_PER_BAR
        mix.add(b, kick, style.kick_gain + (style.accent_kick if pos in (0, 2) else 0.0))
        if style.snare_gain and pos in (1, 3):
            mix.add(b, _snare(rng, clap), style.snare_gain)
        for k in range(style.hihat_division):
            open_hat = open_hat_every and k == style.hihat_division - 1 and pos % open_hat_every == open_hat_every - 1
            mix.add(b + k * period / style.hihat_division, _hihat(rng, bool(open_hat)), 0.8 if k == 0 else 1.0)

    chord_len = style.chord_beats * period
    melody_step = period / style.melody_division
    # Melody: a random walk on the scale, in the octave above the chords, restarting on a chord tone each chord.
    degree = 0
    for c, start in enumerate(np.arange(first, seconds, chord_len)):
        root_degree = progression[c % len(progression)]
        degrees = root_degree + np.array([0, 2, 4])
        # Chords sit two octaves above the bass, clear of the low band beat trackers follow, where the slow
        # attacks and detuned beating of a pad would otherwise read as onsets between beats.
        midis = key + 24 + scale[degrees % 7] + 12 * (degrees // 7)
        chord_beats = beats[(beats >= start - 1e-9) & (beats < start + chord_len - 1e-9)]
        if style.pad == "bright":  # short stabs on the off-beats, an octave above the chord
            stab = note(("stab", c % len(progression)),
                        lambda midis=midis: _chord(midis + 12, period * 0.45, style.pad, rng))
            for b in chord_beats:
                mix.add(b + period / 2, stab)
        else:
            mix.add(start, note(("chord", c % len(progression)),
                                lambda midis=midis: _chord(midis, chord_len, style.pad, rng)))
        bass_midi = key + scale[root_degree % 7]
        for b in chord_beats:
            octave = 12 if rng.random() < 0.15 else 0
            midi = bass_midi + octave
            mix.add(b, note(("bass", midi), lambda midi=midi: _bass_note(midi, period * 0.95, style.bass)), 0.5)
        degree = int(rng.choice(degrees))
        for m_start in np.arange(start, min(start + chord_len, seconds), melody_step):
            if rng.random() < 0.2:  # rests make the phrasing vary from song to song
                continue
            degree = int(np.clip(degree + rng.choice([-2, -1, -1, 0, 1, 1, 2]), 0, 11))
            midi = key + 36 + scale[degree % 7] + 12 * (degree // 7)
            mix.add(m_start, note(("lead", midi), lambda midi=midi: _lead(midi, melody_step * 0.95, style.lead)))

    y = mix.out
    y *= PEAK / max(float(np.max(np.abs(y))), 1e-9)
    return Song(samples=y.astype(np.float32), sample_rate=SAMPLE_RATE, beats=beats,
                downbeats=beats[::BEATS_PER_BAR], tempo=tempo, key=key, minor=minor)
