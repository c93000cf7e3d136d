"""BODY_25 skeleton: joint tables, the pose-sequence value type, conversions, cleaning, normalisation.

Every pose that crosses a module boundary is a :class:`PoseSequence`: a ``[T, 25, 3]`` float32 array of
(x, y, confidence) with x, y in pixels of a ``width`` x ``height`` canvas, plus a frame rate in frames per
second. A joint whose confidence is 0 is absent; its x, y are meaningless.
"""

from __future__ import annotations

import math
import os
import zipfile
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path, require_file

BODY25_JOINTS: tuple[str, ...] = (
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist",
    "MidHip", "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar",
    "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel",
)
NUM_JOINTS = len(BODY25_JOINTS)
JOINT_INDEX: dict[str, int] = {name: i for i, name in enumerate(BODY25_JOINTS)}
ROOT = JOINT_INDEX["MidHip"]
NECK = JOINT_INDEX["Neck"]

# OpenPose's BODY_25 render pairs, in its drawing order (parent, child).
BODY25_LIMBS: tuple[tuple[int, int], ...] = (
    (1, 8), (1, 2), (1, 5), (2, 3), (3, 4), (5, 6), (6, 7), (8, 9), (9, 10), (10, 11), (8, 12),
    (12, 13), (13, 14), (1, 0), (0, 15), (15, 17), (0, 16), (16, 18), (14, 19), (19, 20), (14, 21),
    (11, 22), (22, 23), (11, 24),
)

def _tree_order() -> tuple[tuple[int, int, int], ...]:
    """``(bone, parent, child)`` for every bone, parents before children, walking the skeleton from the root."""
    order, reached, frontier = [], {ROOT}, [ROOT]
    while frontier:
        joint = frontier.pop(0)
        for bone, ends in enumerate(BODY25_LIMBS):
            if joint in ends and (other := ends[1] if ends[0] == joint else ends[0]) not in reached:
                order.append((bone, joint, other))
                reached.add(other)
                frontier.append(other)
    return tuple(order)


# BODY25_LIMBS is a tree: from MidHip, Neck-MidHip is walked towards the neck, the other bones parent to child.
BODY25_TREE: tuple[tuple[int, int, int], ...] = _tree_order()

# OpenPose's BODY_25 joint colours (RGB); a limb takes its child joint's colour.
BODY25_COLORS: tuple[tuple[int, int, int], ...] = (
    (255, 0, 85), (255, 0, 0), (255, 85, 0), (255, 170, 0), (255, 255, 0), (170, 255, 0), (85, 255, 0),
    (0, 255, 0), (255, 0, 0), (0, 255, 85), (0, 255, 170), (0, 255, 255), (0, 170, 255), (0, 85, 255),
    (0, 0, 255), (255, 0, 170), (170, 0, 255), (255, 0, 255), (85, 0, 255), (0, 0, 255), (0, 0, 255),
    (0, 0, 255), (0, 255, 255), (0, 255, 255), (0, 255, 255),
)

# BODY_25 index of each OpenPose COCO-18 joint (COCO-18 lacks MidHip and the six foot points).
COCO18_TO_BODY25: tuple[int, ...] = (0, 1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18)
# Dancing2Music's 14 joints: COCO-18 without the four face points (eyes, ears).
D2M14_TO_BODY25: tuple[int, ...] = COCO18_TO_BODY25[:14]
# BODY_25 index of each COCO-17 joint (AIST++ / MS-COCO order, which has no neck).
COCO17_TO_BODY25: tuple[int, ...] = (0, 16, 15, 18, 17, 5, 2, 6, 3, 7, 4, 12, 9, 13, 10, 14, 11)
# The smallest confidence of a present joint (confidence 0 = absent): the threshold that tells the two apart.
PRESENT_CONFIDENCE = float(np.finfo(np.float32).tiny)


@dataclass
class PoseSequence:
    """A 2D BODY_25 pose sequence.

    Attributes:
        keypoints: ``[T, 25, 3]`` float32; x, y in pixels of the canvas, confidence in [0, 1].
        fps: frames per second.
        width, height: the canvas the pixel coordinates refer to, in pixels.
    """

    keypoints: np.ndarray
    fps: float
    width: int
    height: int

    def __post_init__(self) -> None:
        self.keypoints = np.asarray(self.keypoints, dtype=np.float32)
        if self.keypoints.ndim != 3 or self.keypoints.shape[1:] != (NUM_JOINTS, 3):
            raise ValueError(f"keypoints must have shape [T, 25, 3], got {self.keypoints.shape}")
        if not self.fps > 0:
            raise ValueError(f"fps must be positive, got {self.fps}")
        self.fps = float(self.fps)
        self.width, self.height = int(self.width), int(self.height)

    def __len__(self) -> int:
        return int(self.keypoints.shape[0])

    @property
    def xy(self) -> np.ndarray:
        """``[T, 25, 2]`` pixel coordinates."""
        return self.keypoints[..., :2]

    @property
    def confidence(self) -> np.ndarray:
        """``[T, 25]`` joint confidences."""
        return self.keypoints[..., 2]

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return len(self) / self.fps

    def replace(self, keypoints: np.ndarray | None = None, **changes) -> "PoseSequence":
        """A copy with some fields changed."""
        return PoseSequence(
            keypoints=self.keypoints.copy() if keypoints is None else keypoints,
            fps=changes.get("fps", self.fps),
            width=changes.get("width", self.width),
            height=changes.get("height", self.height),
        )

    def slice_frames(self, start: int, stop: int) -> "PoseSequence":
        """Frames ``start:stop`` (frame indices, not seconds)."""
        return self.replace(self.keypoints[start:stop].copy())

    def save(self, path: str | os.PathLike, **extra: np.ndarray) -> None:
        """Write an ``.npz`` (keys: keypoints, fps, width, height, layout, plus ``extra`` arrays, e.g. the song's
        beat times; :meth:`load` ignores them) atomically."""
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, keypoints=self.keypoints, fps=np.float64(self.fps),
                     width=np.int64(self.width), height=np.int64(self.height), layout=np.str_("BODY_25"),
                     **{k: np.asarray(v) for k, v in extra.items()})

    @classmethod
    def load(cls, path: str | os.PathLike) -> "PoseSequence":
        """Read a file written by :meth:`save`."""
        path = require_file(path, "Pose file")
        try:
            with np.load(path, allow_pickle=False) as z:
                if str(z["layout"]) != "BODY_25":
                    raise KeyError("layout")
                seq = cls(z["keypoints"], float(z["fps"]), int(z["width"]), int(z["height"]))
            if not (math.isfinite(seq.fps) and seq.width > 0 and seq.height > 0):
                raise ValueError("the frame rate and the canvas size must be positive")
        # TypeError: a plain .npy array is no archive; EOFError: an empty file; BadZipFile: a truncated archive
        except (OSError, KeyError, ValueError, TypeError, EOFError, zipfile.BadZipFile) as e:
            raise DancesynthError(
                f"{path} is not a dancesynth pose file (.npz with BODY_25 keypoints, fps, width, height); "
                "create one with `dancesynth extract-poses` or `dancesynth generate`.") from e
        if len(seq) == 0:
            raise DancesynthError(f"{path} holds no frames; give a pose file with at least one frame.")
        if not np.isfinite(seq.keypoints).all():
            raise DancesynthError(f"{path} has keypoints that are not finite numbers; it is damaged, so create it "
                                  "again with `dancesynth extract-poses` or `dancesynth generate`.")
        return seq


def from_partial(points: np.ndarray, to_body25: tuple[int, ...], fps: float, width: int, height: int) -> PoseSequence:
    """Map a ``[T, J, 3]`` array in another joint layout to BODY_25.

    Joints the layout lacks get confidence 0, except Neck and MidHip, which are set to the midpoint of the
    shoulders / hips when both are present (confidence = the smaller of the two).
    """
    points = np.asarray(points, dtype=np.float32)
    out = np.zeros((points.shape[0], NUM_JOINTS, 3), np.float32)
    out[:, list(to_body25)] = points
    for mid, (a, b) in ((NECK, (2, 5)), (ROOT, (9, 12))):
        if mid in to_body25:
            continue
        both = np.minimum(out[:, a, 2], out[:, b, 2])
        out[:, mid, :2] = (out[:, a, :2] + out[:, b, :2]) / 2
        out[:, mid, 2] = both
    return PoseSequence(out, fps, width, height)


def to_coco18(seq: PoseSequence) -> np.ndarray:
    """``[T, 18, 3]`` in OpenPose COCO-18 order (pixels, confidence)."""
    return seq.keypoints[:, list(COCO18_TO_BODY25)].copy()


def to_dancing2music(seq: PoseSequence) -> np.ndarray:
    """``[T, 14, 2]`` pixel coordinates in Dancing2Music's 14-joint order."""
    return seq.keypoints[:, list(D2M14_TO_BODY25), :2].copy()


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` index ranges where the ``[T]`` bool ``mask`` is True, in order."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def interpolate_missing(seq: PoseSequence, min_confidence: float = 0.1, max_gap: int | None = None) -> PoseSequence:
    """Fill absent joints (confidence < ``min_confidence``) linearly in time, per joint.

    Gaps at the start or end are filled by holding the nearest observed value. Filled joints get
    confidence ``min_confidence``; observed joints keep theirs. A joint never observed stays absent, and so
    does a joint over any gap longer than ``max_gap`` frames (confidence 0): a guess held that long would draw
    a limb that is not there.
    """
    kp = seq.keypoints.copy()
    t = np.arange(len(seq))
    for j in range(NUM_JOINTS):
        seen = kp[:, j, 2] >= min_confidence
        if seen.all() or not seen.any():
            continue
        for c in (0, 1):
            kp[~seen, j, c] = np.interp(t[~seen], t[seen], kp[seen, j, c])
        kp[~seen, j, 2] = min_confidence
        for start, stop in true_runs(~seen) if max_gap is not None else []:
            if stop - start > max_gap:
                kp[start:stop, j, 2] = 0.0
    return seq.replace(kp)


def resample(seq: PoseSequence, fps: float) -> PoseSequence:
    """Resample to ``fps``: positions by monotone cubic (PCHIP) interpolation in time, confidence linearly.

    The result has ``round(duration * fps)`` frames (at least 1); frame i sits at time i / fps seconds, and
    times past the last source frame hold its pose. PCHIP has a continuous first derivative (no velocity jumps
    at the source frames, unlike linear interpolation), passes through every source frame and never overshoots
    it. Absent joints' meaningless positions are first filled in time from the frames where the joint is
    present, so they cannot bend the curve of its neighbouring frames. Confidence is interpolated linearly, so
    a joint absent on either side comes out with reduced confidence.
    """
    n_out = max(1, int(round(seq.duration * fps)))
    src_t = np.arange(len(seq)) / seq.fps
    if len(seq) == 1:
        return PoseSequence(np.repeat(seq.keypoints, n_out, axis=0), fps, seq.width, seq.height)
    dst_t = np.minimum(np.arange(n_out) / fps, src_t[-1])
    xy = interpolate_missing(seq, PRESENT_CONFIDENCE).xy.reshape(len(seq), -1).astype(np.float64)
    conf = seq.confidence
    out_xy = PchipInterpolator(src_t, xy, axis=0)(dst_t).reshape(n_out, NUM_JOINTS, 2)
    out_conf = np.stack([np.interp(dst_t, src_t, conf[:, j]) for j in range(NUM_JOINTS)], axis=1)
    return PoseSequence(np.concatenate([out_xy, out_conf[..., None]], axis=-1), fps, seq.width, seq.height)


@dataclass(frozen=True)
class NormParams:
    """What :func:`normalize` removed: canvas centre (pixels) and body scale (pixels per model unit)."""

    center_x: float
    center_y: float
    scale: float
    width: int
    height: int
    fps: float


def body_scale(seq: PoseSequence) -> float:
    """A robust body size in pixels: median Neck-MidHip distance over frames where both are present.

    Falls back to a quarter of the canvas height when the torso is never seen.
    """
    ok = (seq.confidence[:, NECK] > 0) & (seq.confidence[:, ROOT] > 0)
    if not ok.any():
        return seq.height / 4.0
    d = np.linalg.norm(seq.xy[ok, NECK] - seq.xy[ok, ROOT], axis=-1)
    return float(max(np.median(d), 1e-3))


def normalize(seq: PoseSequence, scale: float | None = None) -> tuple[np.ndarray, NormParams]:
    """Pixel poses -> model coordinates, as Dance Revolution does, with an exact inverse.

    Returns ``[T, 25, 2]`` float32: slot ``ROOT`` holds the MidHip position relative to the canvas centre,
    every other slot holds the joint relative to MidHip; all divided by ``scale`` (default
    :func:`body_scale`, so one model unit is one torso length). Confidence is dropped; see
    :func:`denormalize`.
    """
    s = body_scale(seq) if scale is None else float(scale)
    params = NormParams(seq.width / 2.0, seq.height / 2.0, s, seq.width, seq.height, seq.fps)
    xy = seq.xy.astype(np.float64)
    root = xy[:, ROOT:ROOT + 1]
    out = xy - root
    out[:, ROOT] = root[:, 0] - (params.center_x, params.center_y)
    return (out / s).astype(np.float32), params


def denormalize(model_xy: np.ndarray, params: NormParams, confidence: np.ndarray | None = None) -> PoseSequence:
    """Inverse of :func:`normalize`: ``[T, 25, 2]`` model coordinates -> a PoseSequence in pixels.

    ``confidence`` (``[T, 25]``) defaults to 1 for every joint.
    """
    m = np.asarray(model_xy, dtype=np.float64) * params.scale
    root = m[:, ROOT:ROOT + 1] + (params.center_x, params.center_y)
    xy = m + root
    xy[:, ROOT] = root[:, 0]
    conf = np.ones(xy.shape[:2]) if confidence is None else confidence
    kp = np.concatenate([xy, np.asarray(conf, np.float64)[..., None]], axis=-1)
    return PoseSequence(kp, params.fps, params.width, params.height)
