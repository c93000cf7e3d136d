"""Music beats: tracking them in a song, placing them on pose frames, and scoring a tracker against known beats.

Beat times are seconds from the start of the song; on pose frames a beat is the frame nearest to its time
(pose frame ``i`` sits at ``i / fps`` seconds, see :mod:`stage1_pose.features`).
"""

from __future__ import annotations

import numpy as np

from stage1_pose.features import ANALYSIS_SR, log_mel, num_pose_frames, onset_envelope, resample_audio

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
# Onset strength per pose frame is analysed with an 8.3 ms hop at ANALYSIS_SR: finer than any pose frame rate in use.
_ONSET_HOP = 128


def beats_on_frames(times: np.ndarray, num_frames: int, fps: float) -> np.ndarray:
    """``[num_frames]`` bool, True at the pose frame nearest to each beat time (seconds); beats outside the
    frames are dropped."""
    out = np.zeros(num_frames, bool)
    idx = np.round(np.asarray(times, dtype=np.float64) * fps).astype(np.int64)
    out[idx[(idx >= 0) & (idx < num_frames)]] = True
    return out


def _low_onset(samples: np.ndarray, sr: int) -> np.ndarray:
    """Onset strength of the bands under 150 Hz at ``_BEAT_SR`` / ``_BEAT_HOP`` frames per second."""
    y = resample_audio(samples, sr, _BEAT_SR)
    return onset_envelope(log_mel(y, _BEAT_SR, _BEAT_HOP, _BEAT_MELS, _BEAT_FMAX), _BEAT_SR, _BEAT_HOP)


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
    y = resample_audio(samples, sr, ANALYSIS_SR)
    onset = onset_envelope(log_mel(y, ANALYSIS_SR, _ONSET_HOP), ANALYSIS_SR, _ONSET_HOP)
    frame_of = np.round(np.arange(len(onset)) * _ONSET_HOP / ANALYSIS_SR * fps).astype(np.int64)
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
