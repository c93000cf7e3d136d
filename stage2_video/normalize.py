"""Source -> target pose normalisation (Everybody Dance Now, Sec. 3.3).

A pose from elsewhere (a stage-1 dance, another person's video) is mapped onto the target video's canvas so
that the rendered person stands where and as large as the target person did. For each video we measure, from
the ankle y position (pixels, y grows downwards): the closest (largest y) and farthest (smallest y) ankle
positions, and the median body height (ankle to top of head) of the frames near each. A source frame whose
ankle sits a fraction ``b`` of the way from the source's far to close position is scaled by the height ratio
interpolated at ``b`` and moved so that its ankle sits at the same fraction of the target's range.
Horizontally the source's median hip x is moved onto the target's.

A source whose ankles stay within a quarter of its body height (a dance on the spot: its ankle range is foot
lifts and jumps, not depth) gets one scale and one placement for all frames, at the middle of the target's range,
and keeps its own up-and-down motion at that scale; mapping its range onto the target's would stretch a 23-px
foot lift into a 500-px rise.

A range is depth only if the person is taller at its close end, as perspective makes them. A target whose ankle
range is not (a person on a box top and on the lawn in front of it, taller up on the box; crouching near the
camera) gets every frame placed where its person usually stands (the median ankle y) at their usual height (the
median body height), with the source's own up-and-down motion kept at that scale.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import JOINT_INDEX, ROOT, PoseSequence

ANKLES = (JOINT_INDEX["RAnkle"], JOINT_INDEX["LAnkle"])
HEAD = tuple(JOINT_INDEX[n] for n in ("Nose", "REye", "LEye", "REar", "LEar", "Neck"))
MIN_CONFIDENCE = 0.05
# Percentiles standing in for "closest" / "farthest" ankle positions: robust to single bad detections.
FAR_PERCENTILE, CLOSE_PERCENTILE = 5.0, 95.0
# Frames within this share of the ankle range from an extreme contribute to that extreme's median height.
EXTREME_SHARE = 0.2
# Below this ankle-y spread, as a share of the body height, a video has no depth range: one scale for every frame.
DEPTH_SHARE = 0.25


@dataclass(frozen=True)
class BodyStats:
    """Median body statistics of one video, in pixels of its canvas."""

    far_y: float
    close_y: float
    far_height: float
    close_height: float
    center_x: float
    width: int
    height: int
    usual_y: float | None = None
    usual_height: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "BodyStats":
        return cls(**d)

    @property
    def spread(self) -> float:
        return self.close_y - self.far_y

    @property
    def has_depth(self) -> bool:
        """Whether the ankle range is depth (the person moves towards and away from the camera and is taller when
        closer), not foot lifts or two ground levels."""
        wide = self.spread >= DEPTH_SHARE * (self.far_height + self.close_height) / 2
        return wide and self.close_height > self.far_height

    def typical(self) -> tuple[float, float]:
        """(ankle y, body height) where the person usually stands: the medians (statistics stored before they were
        measured: the middle of the ankle range and the mean of its two heights)."""
        if self.usual_y is None or self.usual_height is None:
            return (self.far_y + self.close_y) / 2, (self.far_height + self.close_height) / 2
        return self.usual_y, self.usual_height


def _ankle_y(seq: PoseSequence) -> np.ndarray:
    """``[T]`` mean y of the visible ankles (NaN where neither is visible)."""
    ok = seq.confidence[:, ANKLES] >= MIN_CONFIDENCE
    y = np.where(ok, seq.xy[:, ANKLES, 1], 0.0).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(ok.any(axis=1), y / ok.sum(axis=1), np.nan)


def _body_height(seq: PoseSequence, ankle_y: np.ndarray) -> np.ndarray:
    """``[T]`` ankle y minus the highest visible head joint's y (NaN where unknown)."""
    ok = seq.confidence[:, HEAD] >= MIN_CONFIDENCE
    top = np.where(ok, seq.xy[:, HEAD, 1], np.inf).min(axis=1)
    return np.where(np.isfinite(top), ankle_y - top, np.nan)


def body_stats(seq: PoseSequence) -> BodyStats:
    """Measure :class:`BodyStats` on a sequence; raises when ankles and head are never visible together."""
    ankle = _ankle_y(seq)
    height = _body_height(seq, ankle)
    ok = np.isfinite(height) & (height > 0)
    if not ok.any():
        raise DancesynthError(
            "No frame shows both the ankles and the head, so the pose cannot be normalised; "
            "use a video where the whole body is visible or pass --no-normalize.")
    a, h = ankle[ok], height[ok]
    far_y, close_y = (float(v) for v in np.percentile(a, [FAR_PERCENTILE, CLOSE_PERCENTILE]))
    margin = EXTREME_SHARE * (close_y - far_y)
    far_h = float(np.median(h[a <= far_y + margin]))
    close_h = float(np.median(h[a >= close_y - margin]))
    hips = seq.confidence[:, ROOT] >= MIN_CONFIDENCE
    center_x = float(np.median(seq.xy[hips, ROOT, 0])) if hips.any() else seq.width / 2.0
    return BodyStats(far_y, close_y, far_h, close_h, center_x, seq.width, seq.height, float(np.median(a)),
                     float(np.median(h)))


@dataclass(frozen=True)
class PoseNormalizer:
    """Maps poses measured like ``source`` onto the canvas and body of ``target``."""

    source: BodyStats
    target: BodyStats

    def apply(self, seq: PoseSequence) -> PoseSequence:
        """A copy of ``seq`` on the target canvas: per frame, scaled about the ankle and translated.

        Frames without visible ankles, and every frame of a source without a depth range, use the source's ankle
        range midpoint; onto a target without a depth range, every frame uses the source's and the target's
        :meth:`BodyStats.typical` place and height.
        """
        s, t = self.source, self.target
        if not t.has_depth:
            (source_y, source_h), (target_y, target_h) = s.typical(), t.typical()
            frames = len(seq.keypoints)
            ankle, scale, new_ankle = (np.full(frames, v) for v in (source_y, target_h / source_h, target_y))
        else:
            ankle = _ankle_y(seq)
            middle = (s.far_y + s.close_y) / 2.0
            ankle = np.where(np.isfinite(ankle) & s.has_depth, ankle, middle)
            b = (ankle - s.far_y) / s.spread if s.has_depth else np.full_like(ankle, 0.5)
            scale = t.far_height / s.far_height + b * (t.close_height / s.close_height - t.far_height / s.far_height)
            new_ankle = t.far_y + b * t.spread
        kp = seq.keypoints.astype(np.float64)
        kp[..., 0] = t.center_x + scale[:, None] * (kp[..., 0] - s.center_x)
        kp[..., 1] = new_ankle[:, None] + scale[:, None] * (kp[..., 1] - ankle[:, None])
        return seq.replace(kp.astype(np.float32), width=t.width, height=t.height)

    def to_dict(self) -> dict:
        return {"source": self.source.to_dict(), "target": self.target.to_dict()}


def fit_normalization(source_seq: PoseSequence, target_seq: PoseSequence | BodyStats) -> PoseNormalizer:
    """The normaliser taking ``source_seq``'s poses onto the target (a sequence, or its stored statistics)."""
    target = target_seq if isinstance(target_seq, BodyStats) else body_stats(target_seq)
    return PoseNormalizer(body_stats(source_seq), target)
