"""Movement beats of a pose sequence: where the motion suddenly slows down or changes direction.

Two definitions are in use:

* Dancing to Music (Lee et al. 2019, Eq. 1-2): each joint's frame-to-frame motion is binned by its angle into
  a motion histogram ``D(t, theta)``; its frame difference ``D(t) - D(t - 1)`` is negative where the motion in a
  direction drops, so the summed decrease is a kinematic *offset strength*, the movement analogue of an audio
  onset strength, and its peaks are kinematic beats (:func:`kinematic_offsets`, :func:`kinematic_beats`).
* Bailando / EDGE: local minima of the smoothed mean joint speed (:func:`velocity_minimum_beats`).

All functions take ``[T, J, 2]`` joint positions in any unit (pixels or model coordinates) and return frame
indices; multiply by ``1 / fps`` for seconds.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks


def _check(xy: np.ndarray, fps: float) -> np.ndarray:
    xy = np.asarray(xy, dtype=np.float64)
    if xy.ndim != 3 or xy.shape[-1] != 2:
        raise ValueError(f"xy must have shape [T, J, 2], got {xy.shape}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    return xy


def motion_histogram(xy: np.ndarray, fps: float, bins: int = 8) -> np.ndarray:
    """``D(t, theta)`` of Dancing to Music Eq. 1: ``[T, bins]`` summed joint speeds (units per second) of the
    motion from frame ``t - 1`` to ``t``, binned by motion angle into ``bins`` equal sectors. Row 0 is zero."""
    xy = _check(xy, fps)
    step = np.diff(xy, axis=0)
    speed = np.linalg.norm(step, axis=-1) * fps
    sector = np.floor((np.arctan2(step[..., 1], step[..., 0]) + np.pi) / (2 * np.pi) * bins).astype(np.int64) % bins
    hist = np.zeros((len(xy), bins))
    rows = np.broadcast_to(np.arange(1, len(xy))[:, None], sector.shape)
    np.add.at(hist, (rows, sector), speed)
    return hist


def kinematic_offsets(xy: np.ndarray, fps: float, bins: int = 8) -> np.ndarray:
    """Kinematic offset strength ``[T]`` (units per second, >= 0), Dancing to Music Eq. 2 with its indexing.

    ``offset[t] = sum_theta max(0, D(t - 1, theta) - D(t, theta))``: how much of the motion into frame ``t - 1``,
    per direction, is gone from the motion into frame ``t``; large where the body stops or turns. Frame 0 is 0.
    """
    hist = motion_histogram(xy, fps, bins)
    out = np.zeros(len(hist))
    out[1:] = np.maximum(0.0, hist[:-1] - hist[1:]).sum(axis=1)
    return out


def kinematic_beats(xy: np.ndarray, fps: float, threshold: float = 0.3, min_spacing: float = 0.2,
                    bins: int = 8) -> np.ndarray:
    """Kinematic beat frames ``[K]`` (int64, increasing): peaks of :func:`kinematic_offsets`.

    Args:
        xy: ``[T, J, 2]`` joint positions.
        fps: frames per second.
        threshold: a peak counts when it exceeds this fraction of the 95th percentile of the offset
            strength (relative, so the same value works for pixels and model coordinates).
        min_spacing: seconds between beats at least (the weaker of two close peaks is dropped).
        bins: motion-angle bins of the histogram.
    """
    strength = kinematic_offsets(xy, fps, bins)
    if len(strength) < 3 or not strength.any():
        return np.zeros(0, np.int64)
    level = threshold * np.percentile(strength, 95)
    peaks, _ = find_peaks(strength, height=max(level, 1e-12), distance=max(1, int(round(min_spacing * fps))))
    return peaks.astype(np.int64)


def velocity_minimum_beats(xy: np.ndarray, fps: float, smooth_sigma: float = 0.08) -> np.ndarray:
    """Movement beats as Bailando and EDGE define them: frames ``[K]`` (int64) where the mean joint speed,
    smoothed with a Gaussian of ``smooth_sigma`` seconds, has a strict local minimum.

    The speed at frame ``t`` is the mean over joints of ``|xy[t + 1] - xy[t]|``.
    """
    xy = _check(xy, fps)
    if len(xy) < 3:
        return np.zeros(0, np.int64)
    speed = np.linalg.norm(np.diff(xy, axis=0), axis=-1).mean(axis=1)
    smooth = gaussian_filter1d(speed, sigma=max(smooth_sigma * fps, 1e-3), mode="nearest")
    inner = np.flatnonzero((smooth[1:-1] < smooth[:-2]) & (smooth[1:-1] < smooth[2:])) + 1
    return inner.astype(np.int64)
