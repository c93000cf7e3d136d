"""Music beats: tracking them in a song, the tempo to dance at, and placing them on pose frames.

Three trackers (:data:`BEAT_TRACKERS`): ``dsp``, onset tempograms and dynamic programming (this module);
``learned``, a network and a bar-pointer decoder (:mod:`stage1_pose.beat_tracking`) that also finds the bars;
``combined`` takes the DSP beats, or every other decoded beat, where the network's activations support them
clearly better than its own decoding. :func:`song_beats` runs any of them. Trackers are scored with
``mir_eval.beat`` in the tests and in ``benchmarks/beat_benchmark.py`` (real music, a dev / test split).

Beat times are seconds from the start of the song; on pose frames a beat is the frame nearest to its time
(pose frame ``i`` sits at ``i / fps`` seconds, see :mod:`stage1_pose.music_features`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dancesynth.core.errors import DancesynthError
from stage1_pose.beat_tracking.trackers import BEAT_TRACKERS, DEFAULT_BEAT_TRACKER
from stage1_pose.music_features import ANALYSIS_SR, N_FFT, log_mel, num_pose_frames, onset_envelope, resample_audio

# Beat tracking runs at 22050 Hz with an 11.6 ms hop. Choices measured on benchmarks/beat_benchmark.py (real
# recordings and rendered MIDI pieces with known beats) and on the built-in synthetic songs.
_BEAT_SR = 22050
_BEAT_HOP = 256
# Kick band. Its flux is taken on log(1 + 1000 * power / max): unlike decibels, this barely moves for the faint
# low-frequency leak of loud hi-hats, so the band follows the kick drum (walking or off-beat bass is removed below).
_LOW_HZ = 200.0
_LOW_GAIN = 1000.0
_LOW_SPREAD_BANDS = 5
# The beats are placed on the flux of the bands under 2 kHz plus twice the kick band: cymbals and hi-hats, which
# often play off the beat, are left out of the phase decision.
_PHASE_FMAX = 2000.0
_LOW_WEIGHT = 2.0
# librosa's autocorrelation window for tempo estimation, in seconds.
_TEMPO_WINDOW_SECONDS = 8.0
# Tempo = argmax over 40-240 BPM of (autocorrelation at the beat lag + half of it at twice the lag) x a log-normal
# prior around 120 BPM spread 1.5 octaves. The twice-the-lag term favours tempi whose two-beat groups repeat too,
# which removes the 3:2 errors (a dotted-quarter "beat") that a single lag makes on metal and arpeggios.
_TEMPO_GRID_BPM = np.arange(40.0, 240.0, 0.5)
_TEMPO_HARMONICS = ((1, 1.0), (2, 0.5))
_TEMPO_PRIOR_BPM = 120.0
_TEMPO_PRIOR_OCTAVES = 1.5
# Other tempi scoring within 5 % of the best (its octaves aside, 4 % wide) are tracked too, and the tempo whose beats
# sit on the strongest onsets wins: on a short excerpt two unrelated tempi can score alike (a 95-BPM song's first
# 60 s: 126 BPM 1.22, 95 BPM 1.18). Octaves are left to the prior and the two-beat term, since sparser beats always
# find stronger onsets on average.
_TEMPO_TIE = 0.05
_OCTAVE_WIDTH = 0.06
# Dynamic-programming tightness (librosa's default is 100): real songs keep a steady grid through breaks.
_TIGHTNESS = 400.0
# Swing check: beats that landed on swung off-beats (2/3 of the way through a beat) see the true beat a third of
# a beat later; the beats move there when that position is this many times stronger than the two-thirds one.
_SWING_RATIO = 2.0
# Tempo for dancing: above this, dancers step on every other beat (half time); the built-in styles span 60-135.
DANCE_MAX_BPM = 140.0
# librosa's onset strength (centred) is delayed by half an analysis window, although log_mel's frames are centred on
# their times already: the beats were 40 ms late on the real-music benchmark's exact MIDI grids (librosa#1052).
_ENVELOPE_DELAY = N_FFT // (2 * _BEAT_HOP) * _BEAT_HOP / _BEAT_SR
# The dsp tracker finds no bars: every fourth beat from the first is the usual 4/4 guess.
_DSP_BEATS_PER_BAR = 4
# Onset strength per pose frame is analysed with an 8.3 ms hop at ANALYSIS_SR: finer than any pose frame rate in use.
_ONSET_HOP = 128


def beats_on_frames(times: np.ndarray, num_frames: int, fps: float) -> np.ndarray:
    """``[num_frames]`` bool, True at the pose frame nearest to each beat time (seconds); beats outside the
    frames are dropped."""
    out = np.zeros(num_frames, bool)
    idx = np.round(np.asarray(times, dtype=np.float64) * fps).astype(np.int64)
    out[idx[(idx >= 0) & (idx < num_frames)]] = True
    return out


def _envelopes(samples: np.ndarray, sr: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(full-band, kick-band, phase) onset envelopes at ``_BEAT_SR`` / ``_BEAT_HOP`` frames per second, each
    scaled to unit standard deviation."""
    import librosa

    y = resample_audio(samples, sr, _BEAT_SR)
    mel_db = log_mel(y, _BEAT_SR, _BEAT_HOP)
    freqs = librosa.mel_frequencies(n_mels=mel_db.shape[0], fmax=_BEAT_SR / 2)
    low_power = librosa.db_to_power(mel_db[freqs < _LOW_HZ])
    # A 1-frame harmonic kernel keeps the power each low band shares with its neighbours (median over
    # _LOW_SPREAD_BANDS bands): a kick drum spreads over the low bands, a bass note sits in one and is suppressed.
    low_power = librosa.decompose.hpss(low_power, kernel_size=(1, _LOW_SPREAD_BANDS))[1]
    low = onset_envelope(np.log1p(_LOW_GAIN * low_power / max(float(low_power.max()), 1e-12)), _BEAT_SR, _BEAT_HOP)
    full = onset_envelope(mel_db, _BEAT_SR, _BEAT_HOP)
    phase = _unit(onset_envelope(mel_db[freqs < _PHASE_FMAX], _BEAT_SR, _BEAT_HOP)) + _LOW_WEIGHT * _unit(low)
    return _unit(full), _unit(low), phase


def _unit(envelope: np.ndarray) -> np.ndarray:
    return envelope / max(float(envelope.std()), 1e-9)


def _mean_tempogram(onset: np.ndarray) -> np.ndarray:
    """``[win]`` time-averaged autocorrelation tempogram of an onset envelope: librosa's ``tempogram`` (centred,
    Hann window, each frame's autocorrelation divided by its largest value) averaged over frames, to 1e-15.

    Computed here in blocks of frames, each frame's autocorrelation an FFT along a contiguous row (librosa takes its
    FFTs across the frames' axis, 4x slower on a 3-minute song); the blocks keep memory flat for any song length.
    """
    from numpy.lib.stride_tricks import sliding_window_view
    from scipy import fft, signal

    win = int(round(_TEMPO_WINDOW_SECONDS * _BEAT_SR / _BEAT_HOP))
    n = len(onset)
    frames = sliding_window_view(np.pad(onset, win // 2, mode="linear_ramp", end_values=0), win)[:n]
    window = signal.get_window("hann", win, fftbins=True)
    n_fft = fft.next_fast_len(2 * win - 1, real=True)
    tiny = np.finfo(np.float64).tiny
    total = np.zeros(win)
    # 1024 frames of 689 lags: about 12 MB per block.
    for start in range(0, n, 1024):
        spectrum = fft.rfft(frames[start:start + 1024] * window, n=n_fft, axis=1)
        autocorr = fft.irfft(spectrum.real ** 2 + spectrum.imag ** 2, n=n_fft, axis=1)[:, :win]
        peak = np.abs(autocorr).max(axis=1, keepdims=True)
        total += np.where(peak > tiny, autocorr / np.maximum(peak, tiny), autocorr).sum(axis=0)
    return total / max(n, 1)


def _tempo_candidates(full: np.ndarray, low: np.ndarray) -> list[float]:
    """Tempi in BPM from the summed full-band and kick-band tempograms (see ``_TEMPO_HARMONICS``), best score
    first, then the other local maxima within ``_TEMPO_TIE`` of it that are not its octaves."""
    from scipy.signal import find_peaks

    tg = _mean_tempogram(full) + _mean_tempogram(low)
    lags = 60.0 * _BEAT_SR / _BEAT_HOP / _TEMPO_GRID_BPM
    score = sum(w * np.interp(k * lags, np.arange(len(tg)), tg) for k, w in _TEMPO_HARMONICS)
    score = score * np.exp(-0.5 * (np.log2(_TEMPO_GRID_BPM / _TEMPO_PRIOR_BPM) / _TEMPO_PRIOR_OCTAVES) ** 2)
    best = int(np.argmax(score))
    octaves = np.log2(_TEMPO_GRID_BPM / _TEMPO_GRID_BPM[best])
    off_octave = np.abs(octaves - np.round(octaves)) > _OCTAVE_WIDTH
    peaks = find_peaks(score)[0]
    close = peaks[(score[peaks] >= (1 - _TEMPO_TIE) * score[best]) & off_octave[peaks]]
    return [float(_TEMPO_GRID_BPM[i]) for i in [best, *close]]


def _unswing(beats: np.ndarray, full: np.ndarray) -> np.ndarray:
    """Move beats that sit on swung off-beats a third of a beat later (see ``_SWING_RATIO``)."""
    if len(beats) < 8:
        return beats
    period = float(np.median(np.diff(beats)))

    def strength(fraction: float) -> float:
        idx = np.round((beats[:-1] + fraction * period) * _BEAT_SR / _BEAT_HOP).astype(np.int64)
        idx = idx[(idx >= 1) & (idx < len(full) - 1)]
        return float(np.mean(np.max([full[idx - 1], full[idx], full[idx + 1]], axis=0))) if len(idx) else 0.0

    on, third, half, two_thirds = strength(0.0), strength(1 / 3), strength(0.5), strength(2 / 3)
    if third > _SWING_RATIO * two_thirds and third > half and third > 0.5 * on:
        return beats + period / 3
    return beats


def _local_score(onset: np.ndarray, period: float) -> np.ndarray:
    """``[T]`` float64: the onset envelope over its standard deviation, smoothed by a Gaussian a ``period``-frame
    beat wide (librosa's, term by term in its order: its first frame never counts)."""
    x = onset / (onset.std(ddof=1) + np.finfo(onset.dtype).tiny)
    window = np.exp(-0.5 * (np.arange(-period, period + 1) * 32.0 / period) ** 2)
    half, n = len(window) // 2, len(x)
    score = np.zeros(n)
    for k, w in enumerate(window):
        # score[i] += w * x[i + half - k] for 1 <= i + half - k < n
        lo, hi = max(0, k - half + 1), min(n, n + k - half)
        score[lo:hi] += w * x[lo + half - k:hi + half - k]
    return score


def dp_beats(onset: np.ndarray, bpm: float, frame_rate: float, tightness: float) -> np.ndarray:
    """Beat frames (int64, increasing) of a ``[T]`` onset envelope at a fixed tempo (``bpm``; ``frame_rate`` frames
    per second): Ellis (2007)'s dynamic programme as ``librosa.beat.beat_track(onset_envelope=..., bpm=...,
    tightness=...)`` runs it, the same frames, without compiling librosa's numba kernels (seconds per process).

    Each frame's best predecessor lies half a beat to two beats back, scored by its cumulative score less
    ``tightness`` times the squared log ratio of the gap to the beat; the path ends at the last local maximum of
    the cumulative score above half their median, and frames whose smoothed onset is under half the beats' RMS
    are cut from both ends.
    """
    onset = np.asarray(onset)
    if not onset.any():
        return np.zeros(0, np.int64)
    period = float(np.round(frame_rate * 60.0 / bpm))
    local = _local_score(onset, period)
    n = len(local)
    nearest = int(np.round(period / 2))
    gaps = np.arange(nearest, int(2 * period) + 1)
    # math.log, as the compiled loop calls it: numpy's vectorised log may differ in the last bit.
    penalty = np.array([float(tightness) * (math.log(g) - math.log(period)) ** 2 for g in gaps])
    cumulative = np.empty(n)
    backlink = np.full(n, -1, np.int64)
    # A frame's predecessors are at least ``nearest`` frames back, so a block of that many frames depends only on
    # frames before it.
    block = max(1, nearest)
    for start in range(0, n, block):
        frames = np.arange(start, min(n, start + block))
        before = frames[:, None] - gaps[None, :]
        scores = np.where(before >= 0, cumulative[np.maximum(before, 0)] - penalty, -np.inf)
        rows, best = np.arange(len(frames)), scores.argmax(1)  # argmax: the nearest of equal predecessors
        found = before[rows, best] >= 0
        cumulative[frames] = local[frames] + np.where(found, scores[rows, best], 0.0)
        backlink[frames] = np.where(found, before[rows, best], -1)
    # Before the first frame with a real onset no beat links back.
    first = int(np.argmax(local >= 0.01 * local.max()))
    backlink[:first] = -1
    peaks = np.zeros(n, bool)
    peaks[1:-1] = (cumulative[1:-1] > cumulative[:-2]) & (cumulative[1:-1] >= cumulative[2:])
    peaks[-1] = cumulative[-1] > cumulative[-2]
    high = np.flatnonzero(peaks & (cumulative >= 0.5 * np.median(cumulative[peaks]))) if peaks.any() else []
    last = int(high[-1]) if len(high) else n - 1
    beats = np.zeros(n, bool)
    while last >= 0:
        beats[last] = True
        last = backlink[last]
    smooth = np.convolve(local[beats], np.hanning(5))[2:n + 2]
    strong = np.flatnonzero(local > 0.5 * np.mean(smooth ** 2) ** 0.5)
    beats[:strong[0] if len(strong) else n] = False
    beats[strong[-1] + 1 if len(strong) else n:] = False
    return np.flatnonzero(beats)


def track_beats(samples: np.ndarray, sr: int) -> tuple[float, np.ndarray]:
    """``(tempo in BPM, beat times in seconds)`` of a mono ``[N]`` song at ``sr`` Hz in one pass (see
    :func:`beat_times`)."""
    full, low, phase = _envelopes(samples, sr)
    tracks = []
    for bpm in _tempo_candidates(full, low):
        frames = dp_beats(phase, bpm, _BEAT_SR / _BEAT_HOP, _TIGHTNESS)
        tracks.append((float(phase[frames].mean()) if len(frames) else -np.inf, bpm, frames))
    _, bpm, frames = max(tracks, key=lambda track: track[0])
    beats = _unswing(frames * _BEAT_HOP / _BEAT_SR, full)
    beats = beats - _ENVELOPE_DELAY
    return bpm, beats[beats >= 0]


@dataclass(frozen=True)
class SongBeats:
    """A song's beats and downbeats (float64 seconds, increasing) and its tempo in BPM."""

    beats: np.ndarray
    downbeats: np.ndarray
    bpm: float


def song_beats(samples: np.ndarray, sr: int, tracker: str = DEFAULT_BEAT_TRACKER) -> SongBeats:
    """Beats, downbeats and tempo of a mono ``[N]`` song at ``sr`` Hz by ``tracker`` (:data:`BEAT_TRACKERS`).

    ``learned`` decodes bars of 3 or 4 beats; ``dsp`` gives no bars of its own, so its downbeats are every fourth
    beat from the first; ``combined`` runs both and keeps the learned answer unless the network's activations
    support the DSP beats or half the decoded tempo clearly better
    (:func:`stage1_pose.beat_tracking.tracker.checked`).
    """
    if tracker == "learned":
        from stage1_pose.beat_tracking.tracker import track

        found = track(samples, sr)
        return SongBeats(found.beats, found.downbeats, found.bpm)
    if tracker == "combined":
        from stage1_pose.beat_tracking.tracker import activations, checked, decode_activations

        probs = activations(samples, sr)
        bpm, beats = track_beats(samples, sr)
        found = checked(decode_activations(probs), probs, beats, bpm)
        return SongBeats(found.beats, found.downbeats, found.bpm)
    if tracker == "dsp":
        bpm, beats = track_beats(samples, sr)
        return SongBeats(beats, beats[::_DSP_BEATS_PER_BAR], bpm)
    raise DancesynthError(f"Unknown beat tracker {tracker!r}; choose one of {', '.join(BEAT_TRACKERS)}.")


def beat_times(samples: np.ndarray, sr: int) -> np.ndarray:
    """Beat positions in seconds (``[B]`` float64, increasing) of a mono ``[N]`` song at ``sr`` Hz.

    Tempo from the full-band and kick-band onset tempograms (beat and two-beat lags, a wide prior around 120 BPM),
    then librosa's dynamic-programming tracker on the onsets under 2 kHz plus the kick band (bass notes removed);
    when other tempi, not octaves, score within 5 % of the best, each is tracked and the beats on the strongest
    onsets win; last a swing check that moves beats off swung off-beats, and the times taken back by the onset
    envelope's delay (half an analysis window). Beats are at the song's own metrical level (the tempo to dance at is
    :func:`dance_tempo`).
    """
    return track_beats(samples, sr)[1]


def tempo(samples: np.ndarray, sr: int) -> float:
    """Estimated tempo in beats per minute of a mono ``[N]`` song at ``sr`` Hz."""
    return track_beats(samples, sr)[0]


def dance_tempo(bpm: float) -> float:
    """Tempo to dance at, in steps per minute, for a song of ``bpm`` (:func:`tempo`): halved while above
    ``DANCE_MAX_BPM`` (140).

    People dance fast songs (metal at 170-180 BPM, fast swing) in half time; 140 keeps every built-in style
    (60-135 BPM) and most pop at its own tempo.
    """
    while bpm > DANCE_MAX_BPM:
        bpm /= 2
    return bpm


def onset_strength(samples: np.ndarray, sr: int, fps: float) -> np.ndarray:
    """Full-band onset strength per pose frame, ``[num_pose_frames]`` float32 (librosa's spectral flux units).

    Each pose frame ``i`` takes the strongest onset within half a pose frame of its time ``i / fps``, so short
    onsets between frames are not lost.
    """
    num_frames = num_pose_frames(len(samples), sr, fps)
    y = resample_audio(samples, sr, ANALYSIS_SR)
    onset = onset_envelope(log_mel(y, ANALYSIS_SR, _ONSET_HOP), ANALYSIS_SR, _ONSET_HOP)
    frame_of = np.round(np.arange(len(onset)) * _ONSET_HOP / ANALYSIS_SR * fps).astype(np.int64)
    out = np.zeros(num_frames, np.float32)
    keep = frame_of < num_frames
    np.maximum.at(out, frame_of[keep], onset[keep])
    return out
