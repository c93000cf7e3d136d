"""Motion measures of a dance: joint speed, speed by beat phase, seed distance, movement beats and their chance rate,
and physical plausibility (bone-length error, legs/arms speed ratio, jerk).

Speeds are in the units of the positions per second: pixels per second of the canvas for a
:class:`~dancesynth.core.skeleton.PoseSequence`'s ``xy``; pass ``unit_length=body_scale(seq)`` (the torso length
in pixels) for torso lengths per second, a speed that compares dancers of different sizes.

Two definitions of movement beats are in use:

* Dancing to Music (Lee et al. 2019, Eq. 1-2): each joint's frame-to-frame motion is binned by its angle into
  a motion histogram ``D(t, theta)``; its frame difference ``D(t) - D(t - 1)`` is negative where the motion in a
  direction drops, so the summed decrease is a kinematic *offset strength*, the movement analogue of an audio
  onset strength, and its peaks are kinematic beats (:func:`kinematic_offsets`, :func:`kinematic_beats`).
* Bailando / EDGE: local minima of the smoothed mean joint speed (:func:`velocity_minimum_beats`).

Beat detectors take ``[T, J, 2]`` joint positions in any unit (pixels or model coordinates) and return frame
indices; multiply by ``1 / fps`` for seconds.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks

from dancesynth.core.skeleton import BODY25_LIMBS, JOINT_INDEX, ROOT

LEG_JOINTS: tuple[int, ...] = tuple(JOINT_INDEX[n] for n in (
    "RKnee", "RAnkle", "LKnee", "LAnkle", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel"))
ARM_JOINTS: tuple[int, ...] = tuple(JOINT_INDEX[n] for n in ("RElbow", "RWrist", "LElbow", "LWrist"))

# A kinematic beat within this many pose frames of a music beat is "aligned": +-2 frames = +-133 ms at 15 fps.
DEFAULT_TOLERANCE_FRAMES = 2


def _check(xy: np.ndarray, fps: float) -> np.ndarray:
    xy = np.asarray(xy, dtype=np.float64)
    if xy.ndim != 3 or xy.shape[-1] != 2:
        raise ValueError(f"xy must have shape [T, J, 2], got {xy.shape}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    return xy


def joint_speeds(xy: np.ndarray, fps: float, unit_length: float = 1.0) -> np.ndarray:
    """``[T - 1, J]`` speed of each joint of ``[T, J, 2]`` positions from frame ``t`` to ``t + 1``, in lengths of
    ``unit_length`` per second (default 1: xy's own unit per second, e.g. pixels per second)."""
    xy = _check(xy, fps)
    return np.linalg.norm(np.diff(xy, axis=0), axis=-1) * (fps / unit_length)


def mean_speed(xy: np.ndarray, fps: float, unit_length: float = 1.0) -> float:
    """Mean over frames and joints of :func:`joint_speeds`; 0 for fewer than two frames."""
    speeds = joint_speeds(xy, fps, unit_length)
    return float(speeds.mean()) if speeds.size else 0.0


def speed_by_beat_phase(xy: np.ndarray, beat_frames: np.ndarray, fps: float, bins: int = 10,
                        unit_length: float = 1.0) -> np.ndarray:
    """``[bins]`` mean joint speed in each of ``bins`` equal parts of the intervals between consecutive music beats.

    ``beat_frames``: increasing music beat positions in (fractional) pose frames, seconds x fps. The speed from
    frame ``t`` to ``t + 1`` belongs to time ``t + 0.5``; part ``i`` holds the speeds whose phase (fraction of the
    way from the previous beat to the next) lies in ``[i / bins, (i + 1) / bins)``. Speeds before the first or after
    the last beat are left out; NaN where a part has no speed. Real dances are slowest in the first parts.
    """
    speed = joint_speeds(xy, fps, unit_length).mean(axis=1)
    beats = np.asarray(beat_frames, dtype=np.float64).ravel()
    t = np.arange(len(speed)) + 0.5
    k = np.searchsorted(beats, t) - 1
    inside = (k >= 0) & (k < len(beats) - 1)
    start = beats[k[inside]]
    phase = (t[inside] - start) / (beats[k[inside] + 1] - start)
    part = np.minimum((phase * bins).astype(np.int64), bins - 1)
    return np.array([speed[inside][part == i].mean() if (part == i).any() else np.nan for i in range(bins)])


def bone_lengths(xy: np.ndarray) -> np.ndarray:
    """``[..., B]`` length of each bone of :data:`~dancesynth.core.skeleton.BODY25_LIMBS` in ``[..., 25, 2]``
    positions, in their unit (e.g. pixels)."""
    xy = np.asarray(xy, dtype=np.float64)
    parent, child = np.array(BODY25_LIMBS).T
    return np.linalg.norm(xy[..., child, :] - xy[..., parent, :], axis=-1)


def reference_bone_lengths(xy: np.ndarray) -> np.ndarray:
    """``[B]`` median over frames of :func:`bone_lengths`: a dancer's body, robust to a few bad frames."""
    return np.median(bone_lengths(xy), axis=0)


def bone_length_errors(xy: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``[T, B]`` relative bone-length error ``|length_t - reference| / reference`` of ``[T, 25, 2]`` positions
    against ``[B]`` reference lengths (:func:`reference_bone_lengths`, same unit); NaN for zero-length references
    (a bone the reference dancer lacks)."""
    ref = np.asarray(reference, dtype=np.float64)
    safe = np.where(ref > 0, ref, np.nan)
    return np.abs(bone_lengths(xy) - ref) / safe


def legs_arms_speed_ratio(xy: np.ndarray, fps: float) -> float:
    """Mean :func:`joint_speeds` of the knees, ankles and feet over that of the elbows and wrists (0 = legs still);
    NaN when the arms do not move or there are fewer than two frames."""
    speeds = joint_speeds(xy, fps)
    arms = speeds[:, list(ARM_JOINTS)].mean() if speeds.size else 0.0
    return float(speeds[:, list(LEG_JOINTS)].mean() / arms) if arms > 0 else float("nan")


def upside_down_share(xy: np.ndarray) -> float:
    """Share of the frames of ``[T, 25, 2]`` image positions (y grows downwards) whose neck is below the mid-hip: a
    body standing on its head, which no bone-length or speed measure sees; NaN for no frames."""
    xy = np.asarray(xy)
    if len(xy) == 0:
        return float("nan")
    return float((xy[:, JOINT_INDEX["Neck"], 1] > xy[:, ROOT, 1]).mean())


def mean_jerk(xy: np.ndarray, fps: float) -> float:
    """Mean over frames and joints of the magnitude of the third time derivative of ``[T, J, 2]`` positions
    (third finite difference x ``fps**3``), in units per second cubed; NaN for fewer than four frames."""
    xy = _check(xy, fps)
    if len(xy) < 4:
        return float("nan")
    return float(np.linalg.norm(np.diff(xy, n=3, axis=0), axis=-1).mean() * fps ** 3)


class DanceDistance(NamedTuple):
    """Mean distance between the joints of two dances, in the unit of their positions (e.g. pixels)."""

    joints: float  # all joints where they are on the canvas
    body: float  # joints relative to the root (MidHip): the pose itself
    root: float  # the root's position: where the dancer stands


def dance_distance(a: np.ndarray, b: np.ndarray) -> DanceDistance:
    """Mean per-joint, per-frame distance between two ``[T, 25, 2]`` dances over their common length."""
    n = min(len(a), len(b))
    a, b = np.asarray(a[:n], np.float64), np.asarray(b[:n], np.float64)
    body = (a - a[:, ROOT:ROOT + 1]) - (b - b[:, ROOT:ROOT + 1])
    return DanceDistance(float(np.linalg.norm(a - b, axis=-1).mean()), float(np.linalg.norm(body, axis=-1).mean()),
                         float(np.linalg.norm(a[:, ROOT] - b[:, ROOT], axis=-1).mean()))


def motion_histogram(xy: np.ndarray, fps: float, bins: int = 8) -> np.ndarray:
    """``D(t, theta)`` of Dancing to Music Eq. 1: ``[T, bins]`` summed joint speeds (units per second) of the
    motion from frame ``t - 1`` to ``t``, binned by motion angle into ``bins`` equal sectors. Row 0 is zero."""
    speed = joint_speeds(xy, fps)
    step = np.diff(np.asarray(xy, dtype=np.float64), axis=0)
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
    """Movement beats as Bailando and EDGE define them: frames ``[K]`` (int64) where the mean joint speed from
    frame ``t`` to ``t + 1``, smoothed with a Gaussian of ``smooth_sigma`` seconds, has a strict local minimum."""
    if len(_check(xy, fps)) < 3:
        return np.zeros(0, np.int64)
    speed = joint_speeds(xy, fps).mean(axis=1)
    smooth = gaussian_filter1d(speed, sigma=max(smooth_sigma * fps, 1e-3), mode="nearest")
    inner = np.flatnonzero((smooth[1:-1] < smooth[:-2]) & (smooth[1:-1] < smooth[2:])) + 1
    return inner.astype(np.int64)


def beats_aligned(kinematic_frames: np.ndarray, music_frames: np.ndarray,
                  tolerance_frames: float = DEFAULT_TOLERANCE_FRAMES) -> np.ndarray:
    """``[K]`` bool per kinematic beat (pose frame): is some music beat (fractional pose frame, seconds x fps)
    within ``tolerance_frames`` of it?"""
    k = np.asarray(kinematic_frames, dtype=np.float64).ravel()
    m = np.asarray(music_frames, dtype=np.float64).ravel()
    if k.size == 0 or m.size == 0:
        return np.zeros(k.size, bool)
    return np.abs(k[:, None] - m[None, :]).min(axis=1) <= tolerance_frames


def chance_hit_rate(kinematic_frames: np.ndarray, music_frames: np.ndarray, frames: int, rng: np.random.Generator,
                    shifts: int = 500, tolerance_frames: float = DEFAULT_TOLERANCE_FRAMES) -> float:
    """The beat hit rate movement blind to the music would score: the mean share of aligned kinematic beats
    (:func:`beats_aligned`) after shifting them circularly within the ``frames``-frame dance by ``shifts`` random
    offsets (same count and rhythm, random phase against the beat grid). NaN without kinematic beats."""
    kin = np.asarray(kinematic_frames, dtype=np.int64).ravel()
    if kin.size == 0:
        return float("nan")
    offsets = rng.integers(0, frames, shifts)
    return float(np.mean([beats_aligned((kin + s) % frames, music_frames, tolerance_frames).mean()
                          for s in offsets]))
