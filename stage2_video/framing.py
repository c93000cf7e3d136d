"""Pose sequences -> skeleton label maps at the model resolution, framed exactly like the video frames.

A :class:`Framing` fixes, for one frame, which region of the canvas the model sees (a crop box in canvas
pixels) and how that region is resized to the model's width x height: one uniform scale (aspect kept) and black
padding, never stretching. Frames and poses go through the same framing, so a label map lines up with its frame
pixel for pixel. A video is framed by a :data:`VideoFraming`: one fixed box around everywhere the person goes
(:func:`person_framing`), or, when the person travels across the scene, a box of fixed size that follows them
(:class:`FollowFraming`), so a person crossing the scene still fills the model's image.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import asdict, dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d

from dancesynth.core.draw import draw_pose
from dancesynth.core.skeleton import NECK, ROOT, PoseSequence, body_scale

MIN_CONFIDENCE = 0.05
# Extra room around the joints' bounding box, as a share of its height (head above the nose, feet, motion blur).
CROP_MARGIN = 0.15
# Percentiles of joint positions that bound the crop: robust to a few bad detections.
CROP_PERCENTILES = (0.5, 99.5)
# A following box is used when the fixed box would be this many times taller than it (the person travels).
FOLLOW_GAIN = 1.5
# Standard deviation (seconds) of the Gaussian that smooths the following box's path, so it glides.
FOLLOW_SMOOTH_SECONDS = 0.2
# The following box holds the whole person in this share of the usable frames (a rarely raised hand may leave it).
FOLLOW_COVERAGE = 95.0
# A pose whose torso is outside this range of the video's median torso length is a false detection.
TORSO_RANGE = (0.5, 1.5)


@dataclass(frozen=True)
class Framing:
    """Canvas region ``[x0, x0 + crop_width) x [y0, y0 + crop_height)`` (pixels, may extend past the canvas,
    which reads as black) resized by one factor to ``inner_width x inner_height`` and centred, with black
    padding, in an ``out_width x out_height`` model image."""

    x0: int
    y0: int
    crop_width: int
    crop_height: int
    out_width: int
    out_height: int

    @property
    def inner_width(self) -> int:
        return max(1, round(self.crop_width * self._scale))

    @property
    def inner_height(self) -> int:
        return max(1, round(self.crop_height * self._scale))

    @property
    def _scale(self) -> float:
        return min(self.out_width / self.crop_width, self.out_height / self.crop_height)

    @property
    def pad_x(self) -> int:
        return (self.out_width - self.inner_width) // 2

    @property
    def pad_y(self) -> int:
        return (self.out_height - self.inner_height) // 2

    def points(self, xy: np.ndarray) -> np.ndarray:
        """``[..., 2]`` canvas pixels -> model-image pixels (pixel-centre convention of ``cv2.resize``)."""
        sx = self.inner_width / self.crop_width
        sy = self.inner_height / self.crop_height
        out = np.asarray(xy, np.float32).copy()
        out[..., 0] = (out[..., 0] - self.x0 + 0.5) * sx - 0.5 + self.pad_x
        out[..., 1] = (out[..., 1] - self.y0 + 0.5) * sy - 0.5 + self.pad_y
        return out

    def image(self, frame: np.ndarray) -> np.ndarray:
        """``[H, W, 3]`` (or ``[H, W]``) uint8 frame of the canvas -> ``[out_height, out_width, 3]`` (or
        ``[out_height, out_width]``) uint8 model image."""
        h, w = frame.shape[:2]
        crop = np.zeros((self.crop_height, self.crop_width, *frame.shape[2:]), np.uint8)
        sx0, sy0 = max(self.x0, 0), max(self.y0, 0)
        sx1, sy1 = min(self.x0 + self.crop_width, w), min(self.y0 + self.crop_height, h)
        if sx1 > sx0 and sy1 > sy0:
            crop[sy0 - self.y0:sy1 - self.y0, sx0 - self.x0:sx1 - self.x0] = frame[sy0:sy1, sx0:sx1]
        inner = cv2.resize(crop, (self.inner_width, self.inner_height), interpolation=cv2.INTER_AREA)
        out = np.zeros((self.out_height, self.out_width, *frame.shape[2:]), np.uint8)
        out[self.pad_y:self.pad_y + self.inner_height, self.pad_x:self.pad_x + self.inner_width] = inner
        return out

    def frames(self, seq: PoseSequence) -> list["Framing"]:
        """The framing of each frame of ``seq``: this one for every frame."""
        return [self] * len(seq)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "Framing":
        return cls(**d)


@dataclass(frozen=True)
class FollowFraming:
    """A ``crop_width x crop_height`` box (canvas pixels) that follows the person: in each frame it is centred
    on the person's torso (mid-hip height, between neck and mid-hip across), along a path smoothed over
    ``smooth_seconds``; frames without a usable pose (:func:`usable_frames`) take the path interpolated from
    their neighbours. The box is resized to ``out_width x out_height`` like :class:`Framing`."""

    crop_width: int
    crop_height: int
    out_width: int
    out_height: int
    smooth_seconds: float = FOLLOW_SMOOTH_SECONDS

    def centres(self, seq: PoseSequence) -> np.ndarray:
        """``[T, 2]`` float64 box centres in canvas pixels (the canvas centre where no frame is usable)."""
        present = usable_frames(seq)
        if not present.any():
            return np.tile([seq.width / 2, seq.height / 2], (len(seq), 1))
        torso = np.stack([(seq.xy[:, NECK, 0] + seq.xy[:, ROOT, 0]) / 2, seq.xy[:, ROOT, 1]], axis=1)
        t = np.arange(len(seq))
        path = np.stack([np.interp(t, t[present], torso[present, c]) for c in (0, 1)], axis=1).astype(np.float64)
        return gaussian_filter1d(path, self.smooth_seconds * seq.fps, axis=0, mode="nearest")

    def frames(self, seq: PoseSequence) -> list[Framing]:
        """The :class:`Framing` of each frame of ``seq`` (the box at its place in that frame)."""
        corners = np.floor(self.centres(seq) - (self.crop_width / 2, self.crop_height / 2)).astype(int)
        return [Framing(int(x0), int(y0), self.crop_width, self.crop_height, self.out_width, self.out_height)
                for x0, y0 in corners]

    def to_dict(self) -> dict:
        return {"follow": asdict(self)}


VideoFraming = Framing | FollowFraming


def framing_from_dict(d: dict) -> VideoFraming:
    """The inverse of ``to_dict`` of either framing (a run's meta)."""
    return FollowFraming(**d["follow"]) if "follow" in d else Framing.from_dict(d)


def whole_canvas(width: int, height: int, out_width: int, out_height: int) -> Framing:
    """Letterbox the full ``width x height`` canvas into the model image."""
    return Framing(0, 0, int(width), int(height), int(out_width), int(out_height))


def _to_aspect(w: float, h: float, out_width: int, out_height: int) -> tuple[float, float]:
    """A ``w x h`` box grown along one side to the model image's aspect ratio."""
    aspect = out_width / out_height
    return max(w, h * aspect), max(h, w / aspect)


def person_framing(seq: PoseSequence, out_width: int, out_height: int) -> Framing:
    """The crop around where the person moves in ``seq`` (all frames), grown to the model's aspect ratio.

    Falls back to the whole canvas when no joint is visible or the person covers most of it anyway.
    """
    visible = seq.confidence >= MIN_CONFIDENCE
    if not visible.any():
        return whole_canvas(seq.width, seq.height, out_width, out_height)
    pts = seq.xy[visible]
    (x_lo, y_lo), (x_hi, y_hi) = np.percentile(pts, CROP_PERCENTILES, axis=0)
    margin = CROP_MARGIN * max(y_hi - y_lo, x_hi - x_lo, 1.0)
    x_lo, x_hi, y_lo, y_hi = x_lo - margin, x_hi + margin, y_lo - margin, y_hi + margin
    w, h = _to_aspect(x_hi - x_lo, y_hi - y_lo, out_width, out_height)
    if w >= seq.width and h >= seq.height:
        return whole_canvas(seq.width, seq.height, out_width, out_height)
    cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
    # Slide the box inside the canvas where it fits, so less of the crop is padding.
    x0 = min(max(cx - w / 2, 0.0), max(seq.width - w, 0.0)) if w <= seq.width else cx - w / 2
    y0 = min(max(cy - h / 2, 0.0), max(seq.height - h, 0.0)) if h <= seq.height else cy - h / 2
    return Framing(int(np.floor(x0)), int(np.floor(y0)), int(np.ceil(w)), int(np.ceil(h)), out_width, out_height)


def usable_frames(seq: PoseSequence) -> np.ndarray:
    """``[T]`` bool: frames whose pose has a torso (neck and mid-hip present) of a plausible length
    (:data:`TORSO_RANGE` of the median): the ones fit to learn from and to size a following box by."""
    ok = (seq.confidence[:, NECK] >= MIN_CONFIDENCE) & (seq.confidence[:, ROOT] >= MIN_CONFIDENCE)
    if not ok.any():
        return ok
    torso = np.linalg.norm(seq.xy[:, NECK] - seq.xy[:, ROOT], axis=-1) / body_scale(seq)
    return ok & (torso >= TORSO_RANGE[0]) & (torso <= TORSO_RANGE[1])


def follow_framing(seq: PoseSequence, out_width: int, out_height: int) -> FollowFraming:
    """The smallest following box (model aspect) that holds the whole person around its centre in
    :data:`FOLLOW_COVERAGE` % of the usable frames, with :data:`CROP_MARGIN` to spare."""
    centres = FollowFraming(1, 1, out_width, out_height).centres(seq)
    visible = seq.confidence >= MIN_CONFIDENCE
    offsets = np.where(visible[..., None], np.abs(seq.xy - centres[:, None, :].astype(np.float32)), 0.0)
    reach = offsets.max(axis=1)[usable_frames(seq)]  # [frames, 2]: the farthest joint from the centre per axis
    if not len(reach):
        return FollowFraming(seq.width, seq.height, out_width, out_height)
    half_w, half_h = np.percentile(reach, FOLLOW_COVERAGE, axis=0)
    margin = CROP_MARGIN * 2 * max(half_w, half_h, 1.0)
    w, h = _to_aspect(2 * half_w + margin, 2 * half_h + margin, out_width, out_height)
    return FollowFraming(int(np.ceil(w)), int(np.ceil(h)), out_width, out_height)


def video_framing(seq: PoseSequence, out_width: int, out_height: int) -> VideoFraming:
    """How to frame a target video whose poses are ``seq``: the fixed box of :func:`person_framing`, unless it
    would be :data:`FOLLOW_GAIN` times taller than the box of :func:`follow_framing` (the person travels)."""
    fixed = person_framing(seq, out_width, out_height)
    follow = follow_framing(seq, out_width, out_height)
    return follow if fixed.crop_height > FOLLOW_GAIN * follow.crop_height else fixed


def label_map(keypoints: np.ndarray, framing: Framing) -> np.ndarray:
    """One ``[25, 3]`` pose (canvas pixels + confidence) -> ``[out_height, out_width, 3]`` uint8 RGB label map:
    OpenPose-coloured limbs and joints on black."""
    kp = np.asarray(keypoints, np.float32).copy()
    kp[:, :2] = framing.points(kp[:, :2])
    canvas = np.zeros((framing.out_height, framing.out_width, 3), np.uint8)
    return draw_pose(canvas, kp)


def label_maps(seq: PoseSequence, framing: Framing) -> Iterator[np.ndarray]:
    """Stream :func:`label_map` over every frame of ``seq``."""
    for keypoints in seq.keypoints:
        yield label_map(keypoints, framing)


# The last few plates' crops, keyed by framing and the plate's identity (each plate is kept, so its id is its own).
_PLATE_CROPS: dict[tuple[Framing, int], tuple[np.ndarray, np.ndarray]] = {}
_PLATE_CROPS_KEPT = 4
_PLATE_CROPS_LOCK = threading.Lock()


def plate_crop(framing: Framing, plate: np.ndarray) -> np.ndarray:
    """``framing.image(plate)`` of an ``[H, W, 3]`` uint8 background plate, read-only, remembered for the last few
    framings: a video framed by one fixed box crops its plate once, not once per frame. Plates are never changed
    in place once loaded."""
    key = (framing, id(plate))
    with _PLATE_CROPS_LOCK:  # the renderer warps in a thread of its own
        if key in _PLATE_CROPS:
            return _PLATE_CROPS[key][1]
    crop = framing.image(plate)
    crop.flags.writeable = False
    with _PLATE_CROPS_LOCK:
        while len(_PLATE_CROPS) >= _PLATE_CROPS_KEPT:
            del _PLATE_CROPS[next(iter(_PLATE_CROPS))]
        _PLATE_CROPS[key] = (plate, crop)
    return crop


def condition(keypoints: np.ndarray, framing: Framing, plate: np.ndarray | None = None,
              prior: np.ndarray | None = None) -> np.ndarray:
    """What the model draws one frame from: ``[out_height, out_width, 3]`` uint8 label map of the ``[25, 3]``
    pose, followed (``[..., 6]``) by the same framing's crop of the ``[H, W, 3]`` background ``plate`` when
    given, and by the ``[out_height, out_width, 4]`` warped prior when given (``[..., 10]``)."""
    parts = [label_map(keypoints, framing)]
    if plate is not None:
        parts.append(plate_crop(framing, plate))
    if prior is not None:
        parts.append(prior)
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=2)
