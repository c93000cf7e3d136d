"""Music features aligned to pose frames: the frame convention, the shared spectral analyses and the dispatch to
each method's feature recipe.

Pose frame ``i`` sits at time ``i / fps`` seconds; a song of ``N`` samples at ``sr`` Hz has
:func:`num_pose_frames` pose frames, and every feature has exactly that many rows. Spectral features are
computed at ``ANALYSIS_SR`` Hz with centred STFT frames (analysis frame ``k`` sits at ``k * hop / ANALYSIS_SR``
seconds) and the analysis frame nearest to each pose frame's time is taken (:func:`pose_rows`). At 15 fps the hop
is 512 samples (30 analysis frames per second) and every other frame is kept, as in Dance Revolution.

A feature kind's recipe lives in its method's package (``stage1_pose/models/<method>/music_input.py``) and is
imported on first use, so this module never imports a model and the models may import these helpers.
A recipe module defines ``feature_dim(fps) -> int`` and ``extract(samples, sr, fps, beats) -> [T, feature_dim]``,
and ``VERSION`` (an int, default 1) once its output changes (:func:`cache_name`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from types import ModuleType

import numpy as np

from dancesynth.core.errors import DancesynthError

ANALYSIS_SR = 15360
# Feature kind -> the module of its recipe.
RECIPES: dict[str, str] = {
    "dance_revolution": "stage1_pose.models.dance_revolution.music_input",
    "dancing2music": "stage1_pose.models.dancing2music.music_input",
    "waveform": "stage1_pose.models.ren.music_input",
}
FEATURE_KINDS: tuple[str, ...] = tuple(RECIPES)
# The constant-Q transform halves the signal once per octave, so its hop must be a multiple of 2**6 for 7 octaves.
_CQT_HOP_MULTIPLE = 64
# Spectral analysis pads songs shorter than this with silence: the constant-Q transform's lowest octave needs
# about 3 s of signal. Only rows up to the song's own length are kept.
_MIN_ANALYSIS_SECONDS = 4.0
# Spectral analyses run over blocks of this many frames (with margins), so memory stays flat for any song length.
_BLOCK_FRAMES = 2048
N_FFT = 2048
# Signal a constant-Q block needs beyond its own frames: half the longest (C1, 32.7 Hz) filter at 15360 Hz is
# about 4000 samples; the rest covers the octave-by-octave resampling filters.
_CQT_MARGIN_SAMPLES = 16384


def num_pose_frames(num_samples: int, sr: int, fps: float) -> int:
    """Pose frames for ``num_samples`` samples at ``sr`` Hz: ``floor(num_samples * fps / sr)``, at least 1.

    The one definition every module uses. The tiny epsilon keeps exact multiples (e.g. 1 s at 15 fps = 15)
    from rounding down through floating-point error.
    """
    return max(1, int(np.floor(num_samples * float(fps) / sr + 1e-9)))


def check_kind(kind: str) -> None:
    """Raise a :class:`DancesynthError` naming the known kinds when ``kind`` is not one of them."""
    if kind not in RECIPES:
        raise DancesynthError(f"Unknown audio feature kind {kind!r}; choose one of {', '.join(FEATURE_KINDS)}.")


def _recipe(kind: str) -> ModuleType:
    check_kind(kind)
    return importlib.import_module(RECIPES[kind])


def cache_name(kind: str) -> str:
    """The folder name of ``kind``'s cached features in a dataset: the kind, with ``-v<N>`` appended when its
    recipe module's ``VERSION`` is above 1, so features cached by an older recipe are never read by a newer one."""
    version = getattr(_recipe(kind), "VERSION", 1)
    return kind if version == 1 else f"{kind}-v{version}"


def feature_dim(kind: str, fps: float = 15.0) -> int:
    """Columns of :func:`extract_features` for ``kind`` (the waveform kind depends on ``fps``)."""
    return _recipe(kind).feature_dim(fps)


def extract_features(samples: np.ndarray, sr: int, kind: str, fps: float = 15.0,
                     beats: np.ndarray | None = None) -> np.ndarray:
    """Per-pose-frame music features, ``[num_pose_frames(len(samples), sr, fps), feature_dim(kind, fps)]`` float32.

    Kinds (each documented with its recipe):
        ``dance_revolution``: 438 = MFCC 20, delta-MFCC 20, chroma (CQT) 12, onset strength 1, beat one-hot 1,
        tempogram 384, as in Dance Revolution.
        ``dancing2music``: 28 = MFCC 13, delta-MFCC 13, RMS energy 1, delta-RMS 1.
        ``waveform``: the raw samples of each pose frame (1024 per frame at 15 fps), for Ren et al.

    Args:
        samples: mono ``[N]`` float samples in [-1, 1].
        sr: their sample rate in Hz.
        kind: one of :data:`FEATURE_KINDS`.
        fps: pose frame rate in frames per second.
        beats: the song's beat times in seconds, for recipes that have a beat column (Dance Revolution's);
            None: they track the beats themselves (:func:`stage1_pose.beats.beat_times`).
    """
    return np.ascontiguousarray(_recipe(kind).extract(samples, sr, fps, beats), dtype=np.float32)


def resample_audio(samples: np.ndarray, sr: int, target_sr: int) -> np.ndarray:
    """Mono ``[N]`` samples at ``sr`` Hz -> float32 samples at ``target_sr`` Hz (librosa's default resampler)."""
    import librosa

    samples = np.asarray(samples, dtype=np.float32)
    if samples.ndim != 1:
        raise ValueError(f"samples must be mono [N], got shape {samples.shape}")
    return samples if sr == target_sr else librosa.resample(samples, orig_sr=sr, target_sr=target_sr)


def level_normalised(samples: np.ndarray, sr: int, seconds: float = 3.0, rms: float = 0.1) -> np.ndarray:
    """Mono ``[N]`` samples with a slow automatic gain: each sample times ``rms`` over the RMS of the ``seconds``
    around it (a centred moving window), the gain capped at 100 (+40 dB) so that silence stays quiet. Recordings
    differ in level by tens of dB between songs and between a song's parts; the built-in songs do not."""
    from scipy.ndimage import uniform_filter1d

    y = np.asarray(samples, dtype=np.float32)
    power = uniform_filter1d(y.astype(np.float64) ** 2, max(1, int(round(seconds * sr))), mode="nearest")
    return (y * np.minimum(rms / np.sqrt(power + 1e-12), 100.0)).astype(np.float32)


def analysis_signal(samples: np.ndarray, sr: int) -> np.ndarray:
    """The song at ``ANALYSIS_SR`` Hz, padded with silence to the shortest length spectral analyses need."""
    y = resample_audio(samples, sr, ANALYSIS_SR)
    return np.pad(y, (0, max(0, int(_MIN_ANALYSIS_SECONDS * ANALYSIS_SR) - len(y))))


def analysis_hop(fps: float) -> int:
    """STFT hop in samples at ``ANALYSIS_SR`` for pose frame rate ``fps``: two analysis frames per pose frame,
    rounded to a multiple of 64 samples (a constant-Q transform requirement); 512 at 15 fps."""
    hop = ANALYSIS_SR / (2.0 * float(fps))
    return int(max(_CQT_HOP_MULTIPLE, _CQT_HOP_MULTIPLE * round(hop / _CQT_HOP_MULTIPLE)))


def pose_rows(num_frames: int, fps: float, hop: int, available: int) -> np.ndarray:
    """Index ``[num_frames]`` of the analysis frame nearest to each pose frame's time (clipped to the
    ``available`` frames)."""
    times = np.arange(num_frames) / float(fps)
    return np.clip(np.round(times * ANALYSIS_SR / hop).astype(np.int64), 0, available - 1)


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


def blockwise(y: np.ndarray, hop: int, margin: int, analyse: Callable[[np.ndarray], np.ndarray],
              frames: int | None = None) -> np.ndarray:
    """``analyse`` (a centred frame analysis ``[N] -> [..., frames]``) of the whole of ``y``, computed over
    blocks of ``_BLOCK_FRAMES`` frames with ``margin`` frames of signal either side, concatenated along the last
    (frame) axis."""
    return np.concatenate([analyse(block)[..., keep] for block, keep in _blocks(y, hop, margin, frames)], axis=-1)


def stft_margin(hop: int) -> int:
    """Frames of margin a :func:`blockwise` analysis with an ``N_FFT``-sample window needs at ``hop``."""
    return -(-N_FFT // (2 * hop))


def log_mel(y: np.ndarray, sr: int, hop: int, n_mels: int = 128, fmax: float | None = None) -> np.ndarray:
    """``[n_mels, 1 + len(y) // hop]`` log-power mel spectrogram (dB, 2048-sample window), as librosa's
    ``power_to_db(melspectrogram(y))`` but computed block by block."""
    import librosa

    mel = blockwise(y, hop, stft_margin(hop), lambda block: librosa.feature.melspectrogram(
        y=block, sr=sr, n_fft=N_FFT, hop_length=hop, n_mels=n_mels, fmax=fmax))
    return librosa.power_to_db(mel)


def onset_envelope(mel_db: np.ndarray, sr: int, hop: int) -> np.ndarray:
    """librosa's spectral-flux onset strength ``[frames]`` of a :func:`log_mel` spectrogram."""
    import librosa

    return librosa.onset.onset_strength(S=mel_db, sr=sr, hop_length=hop, n_fft=N_FFT)


def _tuning(y: np.ndarray, sr: int, bins_per_octave: int) -> float:
    """librosa's ``estimate_tuning(y, sr, bins_per_octave=...)`` (fraction of a bin), with its pitch tracking done
    block by block.

    Only each block's voiced spectral peaks (pitch > 0) are kept: the median threshold over them is the one
    song-wide step.
    """
    import librosa

    hop = N_FFT // 4
    pitches, mags = [], []
    for block, keep in _blocks(y, hop, 2):
        pitch, mag = librosa.piptrack(y=block, sr=sr, n_fft=N_FFT, hop_length=hop)
        voiced = pitch[:, keep] > 0
        pitches.append(pitch[:, keep][voiced])
        mags.append(mag[:, keep][voiced])
    pitch, mag = np.concatenate(pitches), np.concatenate(mags)
    threshold = np.median(mag) if len(mag) else 0.0
    return float(librosa.pitch_tuning(pitch[mag >= threshold], resolution=0.01, bins_per_octave=bins_per_octave))


def chroma(y: np.ndarray, sr: int, hop: int) -> np.ndarray:
    """``[12, 1 + len(y) // hop]`` librosa ``chroma_cqt``, block by block with the song's own tuning."""
    import librosa

    # chroma_cqt analyses 36 bins per octave and estimates the tuning at that resolution.
    tuning = _tuning(y, sr, bins_per_octave=36)
    margin = -(-_CQT_MARGIN_SAMPLES // hop)
    return blockwise(y, hop, margin, lambda block: librosa.feature.chroma_cqt(
        y=block, sr=sr, hop_length=hop, n_chroma=12, tuning=tuning))
