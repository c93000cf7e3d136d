"""Temporal clean-up of extracted poses: joints that leap away for a few frames put back (:func:`despike`), then
Savitzky-Golay (zero lag, offline) or One-Euro (causal) smoothing.

The filters act on x, y of each joint over time and leave confidence unchanged. Absent joints (confidence 0) are
neither used nor changed, so run :func:`dancesynth.core.skeleton.interpolate_missing` first to smooth across gaps
(and after :func:`despike`, which marks the joints it drops absent).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import JOINT_INDEX, NECK, ROOT, PoseSequence, true_runs

METHODS = ("savgol", "one-euro", "none")
# Left/right chains a pose estimator swaps, and where along each chain a swap may start: a whole arm or leg, or only
# the forearm or lower leg with the foot (the shoulders or hips left alone); the face's sides.
SWAP_CHAINS = ((("Shoulder", "Elbow", "Wrist"), (0, 1)),
               (("Hip", "Knee", "Ankle", "BigToe", "SmallToe", "Heel"), (0, 1)),
               (("Eye", "Ear"), (0,)))


@dataclass
class SmoothingConfig:
    """Which filter and how strong.

    Attributes:
        method: ``savgol`` (Savitzky-Golay, no lag), ``one-euro`` (causal, adapts to speed) or ``none``.
        window_s: Savitzky-Golay window in seconds (rounded to an odd number of frames, at least ``order + 2``).
        order: Savitzky-Golay polynomial order.
        min_cutoff_hz: One-Euro cut-off frequency at rest, in Hz; lower is smoother.
        beta: One-Euro speed coefficient, per (frame height per second); higher follows fast moves better.
        spike_window_s: half the window, in seconds, whose median position a joint is compared with
            (:func:`despike`); a leap away and back within it is swapped back or dropped. 0: off.
        spike_torso: how far from that median, in the clip's torso lengths (neck to mid-hip), a joint counts as a
            spike.
    """

    method: str = "savgol"
    window_s: float = 0.2
    order: int = 2
    min_cutoff_hz: float = 1.0
    beta: float = 20.0
    spike_window_s: float = 0.12
    spike_torso: float = 0.3

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise DancesynthError(f"Unknown smoothing {self.method!r}; use one of {', '.join(METHODS)}.")
        if (self.window_s < 0 or self.min_cutoff_hz <= 0 or self.beta < 0 or self.order < 1
                or self.spike_window_s < 0 or self.spike_torso <= 0):
            raise DancesynthError("Smoothing and spike windows, cut-off and beta must be positive; check the smoothing "
                                  "options.")


def despike(seq: PoseSequence, config: SmoothingConfig) -> PoseSequence:
    """A copy of ``seq`` with the joints that leap away from where they are just before and after put back: a
    left/right chain swapped back where that brings it nearest, every other such joint marked absent (confidence 0,
    position kept) for :func:`dancesynth.core.skeleton.interpolate_missing` to fill in.

    BlazePose now and then swaps the arms or the legs, or puts an outstretched arm along the body, for one to three
    frames; a person cannot move a hand that far and back that fast, and smoothing would spread the error over its
    window. A joint leaps where it lies more than ``spike_torso`` of the clip's median torso length from the median
    of its present positions within ``spike_window_s`` either side (a Hampel filter; at least half the window
    present, so the first and last ``spike_window_s`` are left as they are).
    """
    half = round(config.spike_window_s * seq.fps)
    kp = seq.keypoints.copy()
    present = kp[..., 2] > 0
    both = present[:, NECK] & present[:, ROOT]
    if half < 1 or len(seq) < 2 * half + 1 or not both.any():
        return seq.replace(kp)
    limit = config.spike_torso * float(np.median(np.linalg.norm(seq.xy[both, NECK] - seq.xy[both, ROOT], axis=-1)))
    xy, centre = _window_medians(kp, half)
    off = np.linalg.norm(xy - centre, axis=-1)  # NaN where absent or too few neighbours
    for names, starts in SWAP_CHAINS:
        pairs = np.array([(JOINT_INDEX["R" + name], JOINT_INDEX["L" + name]) for name in names])
        joints = pairs.T.ravel()
        options = [np.concatenate([pairs[:k], pairs[k:, ::-1]]).T.ravel() for k in starts]
        gaps = np.stack([off[:, joints]] + [np.linalg.norm(xy[:, o] - centre[:, joints], axis=-1) for o in options])
        seen = ~np.isnan(gaps).any(0)  # feet or ears are often unseen on one side: compared on the rest
        best = np.where(seen, gaps, 0).sum(-1).argmin(0)
        with np.errstate(invalid="ignore"):
            leaps = (gaps[0] > limit).any(1)
        for i, option in enumerate(options, 1):
            rows = np.flatnonzero(leaps & (best == i))[:, None]
            kp[rows, joints] = kp[rows, option]
    xy, centre = _window_medians(kp, half)
    with np.errstate(invalid="ignore"):
        kp[np.linalg.norm(xy - centre, axis=-1) > limit, 2] = 0.0
    return seq.replace(kp)


def _window_medians(kp: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray]:
    """``[T, J, 2]`` positions (NaN where absent) and the median of each joint's present positions within
    ``half`` frames either side (NaN where no more than ``half`` are present, and within ``half`` of either end)."""
    xy = np.where(kp[..., 2:] > 0, kp[..., :2].astype(np.float64), np.nan)
    padded = np.pad(xy, ((half, half), (0, 0), (0, 0)), constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1, axis=0)  # [T, J, 2, window]
    enough = (~np.isnan(windows[:, :, :1])).sum(-1) > half
    enough[:half] = enough[len(kp) - half:] = False  # a one-sided window lags a moving joint: the ends go unjudged
    with warnings.catch_warnings():  # a joint absent throughout a window has no median: NaN, as wanted
        warnings.simplefilter("ignore", RuntimeWarning)
        return xy, np.where(enough, np.nanmedian(windows, axis=-1), np.nan)


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
