"""Music features aligned to pose frames, beat tracking and beat scoring.

Pose frame ``i`` sits at time ``i / fps`` seconds; a song of ``N`` samples at ``sr`` Hz has
:func:`num_pose_frames` pose frames, and every feature here has exactly that many rows. Spectral features are
computed at ``ANALYSIS_SR`` Hz with centred STFT frames (analysis frame ``k`` sits at ``k * hop / ANALYSIS_SR``
seconds) and the analysis frame nearest to each pose frame's time is taken. At 15 fps the hop is 512 samples
(30 analysis frames per second) and every other frame is kept, as in Dance Revolution.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from dancesynth.core.errors import DancesynthError

ANALYSIS_SR = 15360
WAVEFORM_SR = 15360
FEATURE_KINDS: tuple[str, ...] = ("dance_revolution", "dancing2music", "waveform")
_FIXED_DIMS = {"dance_revolution": 20 + 20 + 12 + 1 + 1 + 384, "dancing2music": 13 + 13 + 2}
# Column of the beat one-hot in the dance_revolution features (after MFCC, delta-MFCC, chroma and onset).
BEAT_COLUMN = 20 + 20 + 12 + 1
# The constant-Q transform halves the signal once per octave, so its hop must be a multiple of 2**6 for 7 octaves.
_CQT_HOP_MULTIPLE = 64
# Beat tracking: a 5.8 ms hop at 22050 Hz gives tempo resolution well below 1 BPM, and onset strength from the
# mel bands under 150 Hz follows the kick drum rather than off-beat hi-hats.
_BEAT_SR = 22050
_BEAT_HOP = 128
_BEAT_FMAX = 150.0
_BEAT_MELS = 8
# librosa's default autocorrelation window for tempo estimation, in seconds.
_TEMPO_WINDOW_SECONDS = 8.0
# Tempo prior: log-normal around 100 BPM with a 1.5-octave spread. librosa's default (120 BPM, 1 octave) pulls
# slow songs (60-75 BPM) to a wrong faster tempo; this measured better on the synthetic styles and drum loops.
_TEMPO_PRIOR_BPM = 100.0
_TEMPO_PRIOR_OCTAVES = 1.5
# Spectral analysis pads songs shorter than this with silence: the constant-Q transform's lowest octave needs
# about 3 s of signal. Only rows up to the song's own length are kept.
_MIN_ANALYSIS_SECONDS = 4.0
# Spectral analyses run over blocks of this many frames (with margins), so memory stays flat for any song length.
_BLOCK_FRAMES = 2048
_N_FFT = 2048
_DR_TEMPOGRAM_WINDOW = 384
# Signal a constant-Q block needs beyond its own frames: half the longest (C1, 32.7 Hz) filter at 15360 Hz is
# about 4000 samples; the rest covers the octave-by-octave resampling filters.
_CQT_MARGIN_SAMPLES = 16384


def num_pose_frames(num_samples: int, sr: int, fps: float) -> int:
    """Pose frames for ``num_samples`` samples at ``sr`` Hz: ``floor(num_samples * fps / sr)``, at least 1.

    The one definition every module uses. The tiny epsilon keeps exact multiples (e.g. 1 s at 15 fps = 15)
    from rounding down through floating-point error.
    """
    return max(1, int(np.floor(num_samples * float(fps) / sr + 1e-9)))


def feature_dim(kind: str, fps: float = 15.0) -> int:
    """Columns of :func:`extract_features` for ``kind`` (the waveform kind depends on ``fps``)."""
    _check_kind(kind)
    return _waveform_samples_per_frame(fps) if kind == "waveform" else _FIXED_DIMS[kind]


def _check_kind(kind: str) -> None:
    if kind not in FEATURE_KINDS:
        raise DancesynthError(f"Unknown audio feature kind {kind!r}; choose one of {', '.join(FEATURE_KINDS)}.")


def _waveform_samples_per_frame(fps: float) -> int:
    per_frame = WAVEFORM_SR / float(fps)
    if abs(per_frame - round(per_frame)) > 1e-6:
        raise DancesynthError(f"The waveform feature needs {WAVEFORM_SR} / fps to be a whole number of samples, "
                              f"but fps is {fps:g}; use an fps such as 10, 15, 20, 24, 30 or 60.")
    return int(round(per_frame))


def _resample(samples: np.ndarray, sr: int, target_sr: int) -> np.ndarray:
    import librosa

    samples = np.asarray(samples, dtype=np.float32)
    if samples.ndim != 1:
        raise ValueError(f"samples must be mono [N], got shape {samples.shape}")
    return samples if sr == target_sr else librosa.resample(samples, orig_sr=sr, target_sr=target_sr)


def analysis_hop(fps: float) -> int:
    """STFT hop in samples at ``ANALYSIS_SR`` for pose frame rate ``fps``: two analysis frames per pose frame,
    rounded to a multiple of 64 samples (a constant-Q transform requirement); 512 at 15 fps."""
    hop = ANALYSIS_SR / (2.0 * float(fps))
    return int(max(_CQT_HOP_MULTIPLE, _CQT_HOP_MULTIPLE * round(hop / _CQT_HOP_MULTIPLE)))


def _pose_rows(num_frames: int, fps: float, hop: int, available: int) -> np.ndarray:
    """Index of the analysis frame nearest to each pose frame's time (clipped to the frames that exist)."""
    times = np.arange(num_frames) / float(fps)
    return np.clip(np.round(times * ANALYSIS_SR / hop).astype(np.int64), 0, available - 1)


def _frames_to_one_hot(times: np.ndarray, num_frames: int, fps: float) -> np.ndarray:
    """``[num_frames]`` float32 with 1 at the pose frame nearest each time (seconds)."""
    out = np.zeros(num_frames, np.float32)
    idx = np.round(np.asarray(times) * fps).astype(np.int64)
    out[idx[(idx >= 0) & (idx < num_frames)]] = 1.0
    return out


def _blocks(y: np.ndarray, hop: int, margin: int, frames: int | None = None) -> Iterator[tuple[np.ndarray, slice]]:
    """Split a centred frame analysis of ``y`` (``frames`` frames, by default ``1 + len(y) // hop``) into blocks of
    ``_BLOCK_FRAMES`` frames: yields each block's signal, with ``margin`` extra frames of signal on either side, and
    the slice of the block analysis's frames that belong to the block.

    With ``margin * hop`` at least half the analysis window, every kept frame sees the same samples as in one
    whole-song analysis, so memory does not grow with the song's length.
    """
    total = 1 + len(y) // hop if frames is None else frames
    for start in range(0, total, _BLOCK_FRAMES):
        stop = min(total, start + _BLOCK_FRAMES)
        lo = max(0, start - margin)
        yield y[lo * hop:(stop + margin) * hop], slice(start - lo, stop - lo)


def _blockwise(y: np.ndarray, hop: int, margin: int, analyse: Callable[[np.ndarray], np.ndarray],
               frames: int | None = None) -> np.ndarray:
    """``analyse`` (a centred frame analysis ``[N] -> [..., frames]``) of the whole of ``y``, computed over
    :func:`_blocks` and concatenated along the last (frame) axis."""
    return np.concatenate([analyse(block)[..., keep] for block, keep in _blocks(y, hop, margin, frames)], axis=-1)


def _log_mel(y: np.ndarray, sr: int, hop: int, n_mels: int = 128, fmax: float | None = None) -> np.ndarray:
    """``[n_mels, 1 + len(y) // hop]`` log-power mel spectrogram (dB, 2048-sample window), as librosa's
    ``power_to_db(melspectrogram(y))`` but computed block by block."""
    import librosa

    margin = -(-_N_FFT // (2 * hop))
    mel = _blockwise(y, hop, margin, lambda block: librosa.feature.melspectrogram(
        y=block, sr=sr, n_fft=_N_FFT, hop_length=hop, n_mels=n_mels, fmax=fmax))
    return librosa.power_to_db(mel)


def _onset_envelope(log_mel: np.ndarray, sr: int, hop: int) -> np.ndarray:
    """librosa's spectral-flux onset strength ``[frames]`` of a :func:`_log_mel` spectrogram."""
    import librosa

    return librosa.onset.onset_strength(S=log_mel, sr=sr, hop_length=hop, n_fft=_N_FFT)


def _tuning(y: np.ndarray, sr: int, bins_per_octave: int) -> float:
    """librosa's ``estimate_tuning(y, sr, bins_per_octave=...)`` (fraction of a bin), with its pitch tracking done
    block by block.

    Only each block's voiced spectral peaks (pitch > 0) are kept: the median threshold over them is the one
    song-wide step.
    """
    import librosa

    hop = _N_FFT // 4
    pitches, mags = [], []
    for block, keep in _blocks(y, hop, 2):
        pitch, mag = librosa.piptrack(y=block, sr=sr, n_fft=_N_FFT, hop_length=hop)
        voiced = pitch[:, keep] > 0
        pitches.append(pitch[:, keep][voiced])
        mags.append(mag[:, keep][voiced])
    pitch, mag = np.concatenate(pitches), np.concatenate(mags)
    threshold = np.median(mag) if len(mag) else 0.0
    return float(librosa.pitch_tuning(pitch[mag >= threshold], resolution=0.01, bins_per_octave=bins_per_octave))


def _chroma(y: np.ndarray, sr: int, hop: int) -> np.ndarray:
    """``[12, 1 + len(y) // hop]`` librosa ``chroma_cqt``, block by block with the song's own tuning."""
    import librosa

    # chroma_cqt analyses 36 bins per octave and estimates the tuning at that resolution.
    tuning = _tuning(y, sr, bins_per_octave=36)
    margin = -(-_CQT_MARGIN_SAMPLES // hop)
    return _blockwise(y, hop, margin, lambda block: librosa.feature.chroma_cqt(
        y=block, sr=sr, hop_length=hop, n_chroma=12, tuning=tuning))


def _dance_revolution(y: np.ndarray, num_frames: int, fps: float, beats: np.ndarray) -> np.ndarray:
    import librosa

    hop = analysis_hop(fps)
    log_mel = _log_mel(y, ANALYSIS_SR, hop)
    mfcc = librosa.feature.mfcc(S=log_mel, n_mfcc=20)
    mfcc_delta = librosa.feature.delta(mfcc, mode="nearest")
    chroma = _chroma(y, ANALYSIS_SR, hop)
    onset = _onset_envelope(log_mel, ANALYSIS_SR, hop)
    tempogram = _blockwise(onset, 1, _DR_TEMPOGRAM_WINDOW // 2 + 1, lambda block: librosa.feature.tempogram(
        onset_envelope=block, sr=ANALYSIS_SR, hop_length=hop, win_length=_DR_TEMPOGRAM_WINDOW), frames=len(onset))
    available = min(m.shape[-1] for m in (mfcc, chroma, onset[None], tempogram))
    rows = _pose_rows(num_frames, fps, hop, available)
    # Beats are placed on the nearest pose frame rather than subsampled, so none is lost between kept frames.
    beat = _frames_to_one_hot(beats, num_frames, fps)
    return np.concatenate([mfcc[:, rows].T, mfcc_delta[:, rows].T, chroma[:, rows].T, onset[rows, None],
                           beat[:, None], tempogram[:, rows].T], axis=1)


def _dancing2music(y: np.ndarray, num_frames: int, fps: float) -> np.ndarray:
    import librosa

    hop = analysis_hop(fps)
    mfcc = librosa.feature.mfcc(S=_log_mel(y, ANALYSIS_SR, hop), n_mfcc=13)
    rms = _blockwise(y, hop, -(-_N_FFT // (2 * hop)), lambda block: librosa.feature.rms(
        y=block, frame_length=_N_FFT, hop_length=hop))
    stacked = np.concatenate([mfcc, rms])
    delta = librosa.feature.delta(stacked, mode="nearest")
    rows = _pose_rows(num_frames, fps, hop, stacked.shape[-1])
    return np.concatenate([mfcc[:, rows].T, delta[:13, rows].T, rms[:, rows].T, delta[13:, rows].T], axis=1)


def _waveform(y: np.ndarray, num_frames: int, fps: float) -> np.ndarray:
    per_frame = _waveform_samples_per_frame(fps)
    need = num_frames * per_frame
    y = np.pad(y, (0, max(0, need - len(y))))[:need]
    return y.reshape(num_frames, per_frame)


def extract_features(samples: np.ndarray, sr: int, kind: str, fps: float = 15.0) -> np.ndarray:
    """Per-pose-frame music features, ``[num_pose_frames(len(samples), sr, fps), feature_dim(kind, fps)]`` float32.

    Kinds:
        ``dance_revolution``: 438 = MFCC 20, delta-MFCC 20, chroma (CQT) 12, onset strength 1, beat one-hot 1,
        tempogram 384, as in Dance Revolution (librosa at 15360 Hz, hop 512 at 15 fps).
        ``dancing2music``: 28 = MFCC 13, delta-MFCC 13, RMS energy 1, delta-RMS 1.
        ``waveform``: the raw samples of each pose frame at ``WAVEFORM_SR`` Hz (1024 per frame at 15 fps), for
        Ren et al.'s convolutional audio encoder; row ``i`` covers seconds ``[i / fps, (i + 1) / fps)``.

    Args:
        samples: mono ``[N]`` float samples in [-1, 1].
        sr: their sample rate in Hz.
        kind: one of :data:`FEATURE_KINDS`.
        fps: pose frame rate in frames per second.
    """
    _check_kind(kind)
    num_frames = num_pose_frames(len(samples), sr, fps)
    y = _resample(samples, sr, ANALYSIS_SR)
    if kind == "waveform":
        return np.ascontiguousarray(_waveform(y, num_frames, fps), dtype=np.float32)
    y = np.pad(y, (0, max(0, int(_MIN_ANALYSIS_SECONDS * ANALYSIS_SR) - len(y))))
    if kind == "dancing2music":
        out = _dancing2music(y, num_frames, fps)
    else:
        out = _dance_revolution(y, num_frames, fps, beat_times(samples, sr))
    return np.ascontiguousarray(out, dtype=np.float32)


def _low_onset(samples: np.ndarray, sr: int) -> np.ndarray:
    """Onset strength of the bands under 150 Hz at ``_BEAT_SR`` / ``_BEAT_HOP`` frames per second."""
    y = _resample(samples, sr, _BEAT_SR)
    return _onset_envelope(_log_mel(y, _BEAT_SR, _BEAT_HOP, _BEAT_MELS, _BEAT_FMAX), _BEAT_SR, _BEAT_HOP)


def _mean_tempogram(onset: np.ndarray) -> np.ndarray:
    """``[win, 1]`` time-averaged autocorrelation tempogram of an onset envelope, computed in chunks.

    librosa's tempo estimate averages a ``[win, frames]`` tempogram; at this fine hop a whole song's tempogram
    takes gigabytes, so it is accumulated chunk by chunk (each chunk sees half a window of onsets beyond its
    edges, and each frame is counted once), keeping memory flat for any song length.
    """
    import librosa

    win = int(round(_TEMPO_WINDOW_SECONDS * _BEAT_SR / _BEAT_HOP))
    # A tempogram frame sees half a window either side; 512-frame chunks keep each FFT batch near 50 MB.
    chunk, margin = 512, win // 2 + 1
    total, count = np.zeros(win), 0
    for start in range(0, len(onset), chunk):
        lo = max(0, start - margin)
        tg = librosa.feature.tempogram(onset_envelope=onset[lo:start + chunk + margin], sr=_BEAT_SR,
                                       hop_length=_BEAT_HOP, win_length=win)
        keep = tg[:, start - lo:start - lo + min(chunk, len(onset) - start)]
        total += keep.sum(axis=1)
        count += keep.shape[1]
    return (total / max(count, 1))[:, None]


def _track(samples: np.ndarray, sr: int) -> tuple[float, np.ndarray]:
    import librosa

    onset = _low_onset(samples, sr)
    bpm = float(librosa.feature.tempo(tg=_mean_tempogram(onset), sr=_BEAT_SR, hop_length=_BEAT_HOP,
                                      start_bpm=_TEMPO_PRIOR_BPM, std_bpm=_TEMPO_PRIOR_OCTAVES)[0])
    _, beats = librosa.beat.beat_track(onset_envelope=onset, sr=_BEAT_SR, hop_length=_BEAT_HOP, bpm=bpm, units="time")
    return bpm, np.asarray(beats, dtype=np.float64)


def beat_times(samples: np.ndarray, sr: int) -> np.ndarray:
    """Beat positions in seconds (``[B]`` float64, increasing) of a mono ``[N]`` song at ``sr`` Hz.

    Uses librosa's dynamic-programming tracker on low-frequency onset strength (mel bands under 150 Hz, 5.8 ms
    hop), which follows kick drums and ignores off-beat hi-hats.
    """
    return _track(samples, sr)[1]


def tempo(samples: np.ndarray, sr: int) -> float:
    """Estimated tempo in beats per minute of a mono ``[N]`` song at ``sr`` Hz."""
    return _track(samples, sr)[0]


def onset_strength(samples: np.ndarray, sr: int, fps: float) -> np.ndarray:
    """Full-band onset strength per pose frame, ``[num_pose_frames]`` float32 (librosa's spectral flux units).

    Each pose frame ``i`` takes the strongest onset within half a pose frame of its time ``i / fps``, so short
    onsets between frames are not lost.
    """
    num_frames = num_pose_frames(len(samples), sr, fps)
    y = _resample(samples, sr, ANALYSIS_SR)
    hop = _CQT_HOP_MULTIPLE * 2  # 8.3 ms: finer than any pose frame rate in use
    onset = _onset_envelope(_log_mel(y, ANALYSIS_SR, hop), ANALYSIS_SR, hop)
    frame_of = np.round(np.arange(len(onset)) * hop / ANALYSIS_SR * fps).astype(np.int64)
    out = np.zeros(num_frames, np.float32)
    keep = frame_of < num_frames
    np.maximum.at(out, frame_of[keep], onset[keep])
    return out


def beat_f_measure(estimated: np.ndarray, reference: np.ndarray, tolerance: float = 0.07) -> float:
    """F-measure of estimated beat times against reference beat times (both in seconds).

    A reference beat is hit when an estimated beat lies within ``tolerance`` seconds of it; each estimate
    can hit at most one reference (greedy, closest pairs first). Returns 0.0 when either list is empty.
    """
    est = np.sort(np.asarray(estimated, dtype=np.float64).ravel())
    ref = np.sort(np.asarray(reference, dtype=np.float64).ravel())
    if len(est) == 0 or len(ref) == 0:
        return 0.0
    dist = np.abs(ref[:, None] - est[None, :])
    pairs = np.argwhere(dist <= tolerance)
    pairs = pairs[np.argsort(dist[pairs[:, 0], pairs[:, 1]], kind="stable")]
    used_ref, used_est, hits = set(), set(), 0
    for r, e in pairs:
        if r not in used_ref and e not in used_est:
            used_ref.add(r)
            used_est.add(e)
            hits += 1
    if hits == 0:
        return 0.0
    precision, recall = hits / len(est), hits / len(ref)
    return 2 * precision * recall / (precision + recall)
