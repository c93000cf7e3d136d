"""Moving a generated dance's movement beats onto the song's beats by a gentle, smooth retiming.

Every method's dance goes through this step at generation unless it is turned off (``--no-beat-snap``): the
product dances on the beat whatever the method's own timing; ``dancesynth evaluate`` scores the methods without it,
as the papers do. It generalises Dancing2Music's warper (which stretches its dance units onto beats) to any dance:

1. The movement beats are the velocity minima of the smoothed joint speed
   (:func:`dancesynth.core.motion.velocity_minimum_beats`, Bailando's and EDGE's definition).
2. Each may move to a music beat at most ``max_shift`` seconds away. A dynamic programme picks the set of moves
   that puts the most movement beats on beats (ties: the smallest total move), keeping their order, each music
   beat used once, and the local playback rate between consecutive anchors within ``[1 / max_rate, max_rate]``;
   the first and last frames stay where they are, so the dance keeps its length and its sync with the song.
3. The retiming (output time -> source time) is a monotone cubic through the anchors (C1: no speed jumps), and
   the dance is read at the retimed instants in its raw form — root position and bone vectors, cubic in time,
   bone lengths linear — so bones keep their lengths.
4. An accent then reshapes the timing within every beat interval, the beats themselves fixed: the body holds
   briefly after a beat, then moves faster and arrives at speed on the next, stopping within the last frame (a share
   ``accent`` of each interval's timing follows a Beta(2, 1.2) distribution function, the rest stays linear; the
   mean rate is 1). The body then loses its motion in the frame into the beat, so that Dancing2Music's kinematic
   beats (motion lost per frame, which peak mid-deceleration, before the stop) land on the beat as well as the
   velocity minima.
5. Bars (``bars``; measured in docs/methods/beat_tracking.md, "Meter for dancers"): dancers count in bars, so,
   given the song's downbeats, a first pass moves the movement beats that start the largest moves (most path
   travelled until the next movement beat) onto the downbeats, each by at most ``BAR_REACH_BEATS`` beats, before
   the beat passes.

Poses are in model coordinates (:func:`dancesynth.core.skeleton.normalize`), ``[T, 25, 2]``; beats in pose
frames (fractional: seconds x fps).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from scipy.interpolate import PchipInterpolator
from scipy.special import betainc

from dancesynth.core.motion import joint_speeds, velocity_minimum_beats
from stage1_pose.models.kinematics import absolute_positions, bone_vectors, forward_kinematics, joint_lengths

# Beta(a, b) distribution function of the accent: a = 2 starts each beat interval at rest; b = 1.2 keeps the speed up
# until the last frame before the next beat (b = 1.5 spread the stop over two or three frames, and Dancing2Music's
# kinematic beats fired that early).
ACCENT_SHAPE = (2.0, 1.2)
# The bar pass may move a large move's start by up to this many (dance) beats onto a downbeat: a move that starts
# on the beat before or after the bar line, the usual miss, reaches it; the rate bound keeps the retiming gentle.
BAR_REACH_BEATS = 1.0


@dataclass(frozen=True)
class BeatSnap:
    """How far a movement beat may move (seconds), how much playback may speed up or slow down locally (a factor;
    its inverse bounds slowing) and the accent's share of each beat interval's timing (0: none, see the module)."""

    max_shift: float = 0.25
    max_rate: float = 1.5
    # Retiming moves the smoothed speed's minima a little; each pass snaps what the previous one left off the beat.
    passes: int = 3
    accent: float = 0.8
    # Where downbeats are given: the largest moves onto them (see the module).
    bars: bool = True

    def __post_init__(self) -> None:
        if not 0.0 <= self.accent <= 1.0:
            raise ValueError(f"accent must be within [0, 1] (above 1 playback would run backwards), got {self.accent}")


DEFAULT_SNAP = BeatSnap()


def snap_anchors(kinematic: np.ndarray, beats: np.ndarray, frames: int, max_shift_frames: float,
                 max_rate: float, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(source, target)`` anchor frames (float, increasing, first ``(0, 0)``, last ``(frames - 1, frames - 1)``):
    the movement beats ``kinematic`` (frames) that move, each to the music beat (fractional frames) it lands on.

    The largest total ``weights`` (one per movement beat, default 1: the most movement beats) on distinct beats,
    ties broken by the smallest total shift, such that every segment between consecutive anchors plays at a rate
    (target span / source span) within ``[1 / max_rate, max_rate]``.
    """
    end = float(frames - 1)
    k = np.asarray(kinematic, np.float64).ravel()
    w = np.ones(len(k)) if weights is None else np.asarray(weights, np.float64).ravel()
    b = np.asarray(beats, np.float64).ravel()
    b = b[(b > 0) & (b < end)]
    states = [(0.0, 0.0, 0.0)]
    for kin, weight in zip(k, w):
        states += [(kin, beat, weight) for beat in b[np.abs(b - kin) <= max_shift_frames]]
    states.append((end, end, 0.0))
    src, dst, weight = (np.array(column) for column in zip(*states))
    # Each anchor gains its weight less its shift's share, so that all shifts together weigh less than one anchor.
    gain = weight - np.abs(src - dst) / ((max_shift_frames + 1.0) * (len(k) + 2))
    # The best chain's score ending at each state, and the state before it in that chain.
    score = np.full(len(src), -np.inf)
    score[0] = 0.0
    back = np.full(len(src), -1)
    for i in range(1, len(src)):
        span_src, span_dst = src[i] - src[:i], dst[i] - dst[:i]
        ok = (span_src > 0) & (span_dst > 0)
        rate = np.divide(span_dst, span_src, out=np.zeros(i), where=ok)
        ok &= (rate >= 1.0 / max_rate) & (rate <= max_rate) & np.isfinite(score[:i])
        if not ok.any():
            continue
        candidates = np.where(ok, score[:i], -np.inf)
        best = int(np.argmax(candidates))
        score[i], back[i] = candidates[best] + gain[i], best
    if not np.isfinite(score[-1]):
        return np.array([0.0, end]), np.array([0.0, end])
    chain = [len(src) - 1]
    while chain[-1] != 0:
        chain.append(int(back[chain[-1]]))
    chain.reverse()
    return src[chain], dst[chain]


def snap_to_beats(poses: np.ndarray, beat_frames: np.ndarray, fps: float, settings: BeatSnap = DEFAULT_SNAP,
                  downbeat_frames: np.ndarray | None = None) -> np.ndarray:
    """``[T, 25, 2]`` model-coordinate poses -> the same dance retimed so that its movement beats land on
    ``beat_frames`` (fractional pose frames) where a gentle retiming can put them (see the module's doc); with
    ``downbeat_frames`` (fractional pose frames, a subset of the beats) the largest moves start on the downbeats
    (``settings.bars``).

    Each pass finds the anchors on the dance retimed so far; the passes' retimings are composed and the dance is
    read once, from the original frames, so that it is interpolated (and smoothed) only once."""
    frames = len(poses)
    if frames < 4 or len(beat_frames) == 0:
        return poses
    # Each pass: (music frames to land on, reach in frames, whether movement beats weigh by the move they start).
    bar_pass: list[tuple[np.ndarray, float, bool]] = []
    has_bars = downbeat_frames is not None and len(downbeat_frames) > 0
    if settings.bars and has_bars and len(beat_frames) > 1:
        bar_pass = [(downbeat_frames, BAR_REACH_BEATS * float(np.median(np.diff(beat_frames))), True)]
    passes = bar_pass + [(beat_frames, settings.max_shift * fps, False)] * settings.passes
    read_at = _reader(poses)
    t = np.arange(frames, dtype=np.float64)
    source_time, snapped = t, poses
    for targets, reach, by_size in passes:
        positions = absolute_positions(np.asarray(snapped, np.float64))
        kinematic = velocity_minimum_beats(positions, fps)
        weights = None
        if by_size:  # the largest move weighs as much as one anchor of the beat passes
            sizes = move_sizes(positions, fps, kinematic)
            weights = sizes / max(float(sizes.max(initial=0.0)), 1e-12)
        src, dst = snap_anchors(kinematic, targets, frames, reach, settings.max_rate, weights)
        if len(src) == 2:
            # Nothing moves. After the bar pass the beat passes still run; after a beat pass the dance is the one
            # this pass read, so every later beat pass would find the same nothing.
            if by_size:
                continue
            break
        step = np.clip(PchipInterpolator(dst, src)(t), 0.0, frames - 1.0)
        source_time = np.interp(step, t, source_time)
        snapped = read_at(source_time)
    if settings.accent > 0:
        snapped = read_at(np.interp(accent_times(frames, beat_frames, settings.accent), t, source_time))
    return snapped


def move_sizes(xy: np.ndarray, fps: float, movement_beats: np.ndarray) -> np.ndarray:
    """``[K]`` size of the move each movement beat (pose frame, increasing) starts: the mean joint path length of
    ``[T, J, 2]`` positions (their unit) from it to the next movement beat, or to the end of the dance."""
    speed = joint_speeds(xy, fps).mean(axis=1) / fps
    travelled = np.concatenate([[0.0], np.cumsum(speed)])  # [T]: path length from frame 0 to frame t
    starts = np.asarray(movement_beats, np.int64).ravel()
    ends = np.append(starts[1:], len(xy) - 1)
    return travelled[ends] - travelled[starts]


def accent_times(frames: int, beat_frames: np.ndarray, accent: float) -> np.ndarray:
    """``[frames]`` output frame -> frame of the unaccented dance to show there: identity before the first and after
    the last beat and on every beat; between two beats a blend, ``accent`` : ``1 - accent``, of the Beta(2, 1.2)
    distribution function and the identity over the interval (a hold after a beat, a sharp stop on the next)."""
    t = np.arange(frames, dtype=np.float64)
    b = np.asarray(beat_frames, np.float64).ravel()
    b = np.unique(b[(b > 0) & (b < frames - 1)])
    out = t.copy()
    if len(b) < 2:
        return out
    segment = np.searchsorted(b, t, side="right") - 1
    inside = (segment >= 0) & (segment < len(b) - 1)
    lo = b[segment[inside]]
    span = b[segment[inside] + 1] - lo
    u = (t[inside] - lo) / span
    out[inside] = lo + span * ((1.0 - accent) * u + accent * betainc(ACCENT_SHAPE[0], ACCENT_SHAPE[1], u))
    return out


def _reader(poses: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """A function reading the ``[T, 25, 2]`` model-coordinate poses at ``[N]`` fractional frame times: root position
    and bone vectors cubic (PCHIP) in time, bone lengths linear, joints placed again by forward kinematics. The
    interpolants are fitted once, for every pass."""
    frames = len(poses)
    pose_t = torch.as_tensor(np.asarray(poses, np.float64))
    raw, lengths = bone_vectors(pose_t).numpy(), joint_lengths(pose_t).numpy()
    t = np.arange(frames)
    raw_curve = PchipInterpolator(t, raw.reshape(frames, -1), axis=0)
    dtype = np.asarray(poses).dtype

    def read_at(times: np.ndarray) -> np.ndarray:
        raw_at = raw_curve(times).reshape(len(times), *raw.shape[1:])
        lengths_at = np.stack([np.interp(times, t, lengths[:, j]) for j in range(lengths.shape[1])], axis=1)
        return forward_kinematics(torch.from_numpy(raw_at), torch.from_numpy(lengths_at)).numpy().astype(dtype)

    return read_at
