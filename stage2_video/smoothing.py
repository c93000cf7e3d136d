"""Temporal smoothing of extracted poses: Savitzky-Golay (zero lag, offline) or One-Euro (causal).

Both act on x, y of each joint over time and leave confidence unchanged. Absent joints (confidence 0) are
neither used nor changed, so run :func:`dancesynth.core.skeleton.interpolate_missing` first to smooth across gaps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import PoseSequence, true_runs

METHODS = ("savgol", "one-euro", "none")


@dataclass
class SmoothingConfig:
    """Which filter and how strong.

    Attributes:
        method: ``savgol`` (Savitzky-Golay, no lag), ``one-euro`` (causal, adapts to speed) or ``none``.
        window_s: Savitzky-Golay window in seconds (rounded to an odd number of frames, at least ``order + 2``).
        order: Savitzky-Golay polynomial order.
        min_cutoff_hz: One-Euro cut-off frequency at rest, in Hz; lower is smoother.
        beta: One-Euro speed coefficient, per (frame height per second); higher follows fast moves better.
    """

    method: str = "savgol"
    window_s: float = 0.2
    order: int = 2
    min_cutoff_hz: float = 1.0
    beta: float = 20.0

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise DancesynthError(f"Unknown smoothing {self.method!r}; use one of {', '.join(METHODS)}.")
        if self.window_s < 0 or self.min_cutoff_hz <= 0 or self.beta < 0 or self.order < 1:
            raise DancesynthError("Smoothing window, cut-off and beta must be positive; check the smoothing options.")


def smooth(seq: PoseSequence, config: SmoothingConfig) -> PoseSequence:
    """A smoothed copy of ``seq`` (same shape, fps and canvas)."""
    if config.method == "none" or len(seq) < 3:
        return seq.replace()
    if config.method == "savgol":
        return _savgol(seq, config)
    return _one_euro(seq, config)


def _savgol(seq: PoseSequence, config: SmoothingConfig) -> PoseSequence:
    kp = seq.keypoints.copy()
    window = max(int(round(config.window_s * seq.fps)) | 1, config.order + 2 | 1)
    for j in range(kp.shape[1]):
        for start, stop in true_runs(kp[:, j, 2] > 0):
            if stop - start >= window:
                kp[start:stop, j, :2] = savgol_filter(kp[start:stop, j, :2], window, config.order, axis=0)
    return seq.replace(kp)


def _alpha(cutoff_hz: np.ndarray, fps: float) -> np.ndarray:
    tau = 1.0 / (2 * np.pi * cutoff_hz)
    return 1.0 / (1.0 + tau * fps)


def _one_euro(seq: PoseSequence, config: SmoothingConfig) -> PoseSequence:
    """Casiez et al. 2012, vectorised over joints; speeds measured in frame heights per second."""
    kp = seq.keypoints.copy()
    xy = kp[..., :2].astype(np.float64) / seq.height
    present = kp[..., 2] > 0
    out = xy.copy()
    speed = np.zeros_like(xy)
    d_alpha = _alpha(np.array(1.0), seq.fps)  # the derivative's own cut-off, 1 Hz as in the paper
    for t in range(1, len(seq)):
        both = (present[t] & present[t - 1])[:, None]
        raw_speed = (xy[t] - out[t - 1]) * seq.fps
        speed[t] = np.where(both, speed[t - 1] + d_alpha * (raw_speed - speed[t - 1]), 0.0)
        a = _alpha(config.min_cutoff_hz + config.beta * np.abs(speed[t]), seq.fps)
        out[t] = np.where(both, out[t - 1] + a * (xy[t] - out[t - 1]), xy[t])
    kp[..., :2] = np.where(present[..., None], out * seq.height, kp[..., :2])
    return seq.replace(kp)
