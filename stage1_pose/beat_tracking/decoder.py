"""Beats and downbeats from frame activations: a Viterbi pass over a bar-pointer state space (Krebs, Böck &
Widmer 2015, "An efficient state-space model for joint tempo and meter tracking", as madmom's
``DBNDownBeatTrackingProcessor`` uses it), written here in numpy.

A state is (metre M, tempo tau in frames per beat, beat k of the bar, position p in the beat, 0 <= p < tau). Each
frame p moves on by one; at the end of a beat the next beat of the bar starts, and only there may the tempo change,
to tau' with probability proportional to ``exp(-transition_lambda * |tau / tau' - 1|)``. The first
``1 / observation_lambda`` (at least ``observation_frames`` frames) of beat 0 observes the downbeat activation, that
of the other beats the beat activation, every other position ``(1 - beat - downbeat) / (observation_lambda - 1)``.
Metres do not mix: the one whose best path scores highest wins (one Viterbi pass over all their states).
Activations are per frame at ``fps``; times come back in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_EPS = 1e-7
# A beat's tempo may move this many tempo states (about 2 % each) from the previous beat's: exp(-lambda * 0.1)
# makes larger steps negligible anyway.
_BAND = 5


@dataclass(frozen=True)
class DecoderConfig:
    """Tempo range in BPM, tempo states (log-spaced integer beat lengths), metres in beats per bar, the tempo
    change and observation parameters, and ``threshold``: frames before the first and after the last activation
    above it carry no beats."""

    min_bpm: float = 55.0
    max_bpm: float = 225.0
    num_tempi: int = 60
    metres: tuple[int, ...] = (3, 4)
    transition_lambda: float = 100.0
    # 1/10 of a beat, at least 2 frames (madmom: 1/16 at 100 fps): at 50 fps one-frame regions let beats drift off
    # the network's peaks, and wider ones cost a slow path more low-activation frames a beat than its double, so
    # slow songs went to double tempo (1/8 before; on the benchmark's dev and held-out pieces 1/10 to 1/13 beat it).
    observation_lambda: int = 10
    observation_frames: int = 2
    threshold: float = 0.05


DEFAULT_DECODER = DecoderConfig()


@dataclass(frozen=True)
class Decoded:
    """Beat and downbeat times in seconds (float64, increasing), the bar's beats and the median tempo in BPM."""

    beats: np.ndarray
    downbeats: np.ndarray
    metre: int
    bpm: float


def beat_lengths(fps: float, config: DecoderConfig) -> np.ndarray:
    """Tempo states: unique integer beat lengths in frames, log-spaced from ``max_bpm`` to ``min_bpm``."""
    lo, hi = 60.0 * fps / config.max_bpm, 60.0 * fps / config.min_bpm
    taus = np.unique(np.round(np.geomspace(lo, hi, config.num_tempi)).astype(np.int64))
    return taus[taus >= 2]


class _Space:
    """All metres' bar-pointer states in one flat array. A slot is one beat (metre, tempo, beat k of the bar) at
    one tempo: ``taus`` consecutive states. Slot ``s`` may follow the slots ``sources[s]`` (the previous beat of the
    bar at a tempo within ``_BAND`` states of its own), with log probabilities ``log_trans[s]``."""

    def __init__(self, taus: np.ndarray, metres: tuple[int, ...], config: DecoderConfig) -> None:
        self.taus = taus
        slots = [(m, i, k) for m in metres for i in range(len(taus)) for k in range(m)]
        self.slot_metre = np.array([m for m, _, _ in slots], np.int64)
        self.slot_beat = np.array([k for _, _, k in slots], np.int64)
        self.slot_tau = np.array([taus[i] for _, i, _ in slots], np.int64)
        self.first = np.concatenate([[0], np.cumsum(self.slot_tau)[:-1]])
        self.last = self.first + self.slot_tau - 1
        self.size = int(self.slot_tau.sum())
        index = {slot: n for n, slot in enumerate(slots)}
        band = np.arange(-_BAND, _BAND + 1)
        # A missing source (beyond the tempo range) points at a padding entry holding -inf.
        self.sources = np.full((len(slots), len(band)), len(slots), np.int64)
        self.log_trans = np.zeros((len(slots), len(band)))
        for n, (m, i, k) in enumerate(slots):
            for b, j in enumerate(i + band):
                if 0 <= j < len(taus):
                    self.sources[n, b] = index[(m, int(j), (k - 1) % m)]
                    self.log_trans[n, b] = -config.transition_lambda * abs(taus[j] / taus[i] - 1.0)
        self.log_trans -= np.logaddexp.reduce(np.where(self.sources < len(slots), self.log_trans, -np.inf), axis=1,
                                              keepdims=True)
        # States that observe a beat or a downbeat: the first 1/lambda of each beat, at least observation_frames.
        width = np.maximum(config.observation_frames, self.slot_tau // config.observation_lambda)
        observing = np.concatenate([self.first[n] + np.arange(width[n]) for n in range(len(slots))])
        down = np.repeat(self.slot_beat == 0, width)
        self.beat_states, self.down_states = observing[~down], observing[down]
        self.state_slot = np.repeat(np.arange(len(slots)), self.slot_tau)


def _viterbi(space: _Space, log_obs: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """(metre, beat frames, downbeat frames) of the best path for ``log_obs`` ``[T, 3]`` (none, beat, downbeat)."""
    frames = len(log_obs)
    gain_beat, gain_down = log_obs[:, 1] - log_obs[:, 0], log_obs[:, 2] - log_obs[:, 0]
    delta = np.zeros(space.size)
    delta[space.beat_states] += gain_beat[0]
    delta[space.down_states] += gain_down[0]
    spare = np.empty_like(delta)
    ends = np.full(len(space.first) + 1, -np.inf)
    back = np.empty((frames, len(space.first)), np.int8)
    for t in range(1, frames):
        ends[:-1] = delta[space.last]
        cand = ends[space.sources] + space.log_trans
        choice = cand.argmax(axis=1)
        back[t] = choice
        spare[1:] = delta[:-1]
        spare[space.first] = np.take_along_axis(cand, choice[:, None], axis=1)[:, 0]
        spare[space.beat_states] += gain_beat[t]
        spare[space.down_states] += gain_down[t]
        delta, spare = spare, delta
    state = int(np.argmax(delta))
    slot = int(space.state_slot[state])
    p = state - int(space.first[slot])
    beats, downbeats = [], []
    t = frames - 1
    while t - p >= 0:
        start = t - p
        beats.append(start)
        if space.slot_beat[slot] == 0:
            downbeats.append(start)
        if start == 0:
            break
        slot = int(space.sources[slot, back[start, slot]])
        t, p = start - 1, int(space.slot_tau[slot]) - 1
    return int(space.slot_metre[slot]), np.array(beats[::-1], np.int64), np.array(downbeats[::-1], np.int64)


def decode(beat: np.ndarray, downbeat: np.ndarray, fps: float, config: DecoderConfig = DEFAULT_DECODER) -> Decoded:
    """Beats and downbeats of per-frame activations at ``fps``: ``beat`` ``[T]`` the probability of a beat that is
    not a downbeat, ``downbeat`` ``[T]`` that of a downbeat (both in [0, 1], summing to at most 1).

    Frames outside the span from the first to the last frame where either exceeds ``threshold`` (from
    ``observation_frames`` before it) are skipped.
    """
    beat, downbeat = np.asarray(beat, np.float64), np.asarray(downbeat, np.float64)
    active = np.flatnonzero(np.maximum(beat, downbeat) > config.threshold)
    empty = np.zeros(0, np.float64)
    if len(active) < 2:
        return Decoded(empty, empty, config.metres[0], 0.0)
    # A beat region may start just before the first frame above the threshold.
    lo, hi = max(0, int(active[0]) - config.observation_frames), int(active[-1]) + 1
    b, d = beat[lo:hi], downbeat[lo:hi]
    log_obs = np.log(np.stack([np.clip(1.0 - b - d, 0.0, 1.0) / (config.observation_lambda - 1), b, d], axis=1)
                     + _EPS)
    metre, beat_frames, down_frames = _viterbi(_Space(beat_lengths(fps, config), config.metres, config), log_obs)
    times = (beat_frames + lo) / fps
    bpm = 60.0 / float(np.median(np.diff(times))) if len(times) > 1 else 0.0
    return Decoded(times, (down_frames + lo) / fps, metre, bpm)
