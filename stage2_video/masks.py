"""Person masks: where the target person is in each frame, drawn from the pose or segmented from the pixels.

:func:`person_mask` draws a pose with thick limbs, a head disc and a margin, all in torso lengths: a generous
region where the person may be, for the blend of the composite and as the fallback below.

mediapipe's Pose graph (``enable_segmentation=True``, model bundled in the wheel) returns a soft person mask with
the landmarks. It misses small figures in a large frame, so it runs on each frame's person crop (the box around
that frame's pose, grown by :data:`CROP_GROWTH`), and what it returns is kept only near the pose (so a second
person or a prop next to the target never counts). Frames where it finds nobody fall back to :func:`person_mask`.
The masks are framed like the training frames (:class:`stage2_video.framing.Framing`) and cached in the run folder
as a uint8 ``.npy`` memory map keyed by the video's content, the framing and the poses, like the frames
(:func:`stage2_video.training_data.cache_file`). A graph runs on one core, so :func:`cache_masks` runs one per core
on consecutive stretches of the video side by side (:func:`dancesynth.core.media.frame_stretches`).
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np
import torch

from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import frame_stretches, read_frames
from dancesynth.core.progress import track
from dancesynth.core.skeleton import BODY25_LIMBS, JOINT_INDEX, NECK, ROOT, PoseSequence, body_scale
from stage2_video.extract import native_logs_hidden_unless_debug
from stage2_video.framing import MIN_CONFIDENCE, Framing, VideoFraming
from stage2_video.training_data import cache_file, framed_key, poses_digest

# Person drawing, in torso lengths (Neck-MidHip): limb thickness, head disc radius, hand length past the wrist.
LIMB_WIDTH = 0.45
HEAD_RADIUS = 0.4
HAND_LENGTH = 0.35
# A frame's torso may look shorter (bending towards the camera) but not below this share of the reference.
MIN_TORSO_SHARE = 0.7
_FACE = [JOINT_INDEX[n] for n in ("Nose", "REye", "LEye", "REar", "LEar")]
_TORSO = [JOINT_INDEX[n] for n in ("Neck", "RShoulder", "LShoulder", "MidHip", "RHip", "LHip")]
_FOREARMS = [(JOINT_INDEX["RElbow"], JOINT_INDEX["RWrist"]), (JOINT_INDEX["LElbow"], JOINT_INDEX["LWrist"])]
_SHIFT = 4  # sub-pixel bits for OpenCV drawing
# The crop the segmenter sees: the pose's bounding box grown by this share of its longer side on every side.
CROP_GROWTH = 0.3
# Longest side the crop is resampled to (the segmenter itself works at 256 x 256).
SEGMENT_SIZE = 256
# Soft mask value from which a pixel belongs to the person.
MASK_THRESHOLD = 0.5
# The segmenter's answer is kept within this many torso lengths of the drawn pose (hair, loose clothes, hands).
KEEP_MARGIN = 0.6
# Fallback where the segmenter finds nobody: the pose drawn with this margin (torso lengths).
FALLBACK_MARGIN = 0.1


def torso_length(keypoints: np.ndarray, reference: float) -> float:
    """One pose's Neck-MidHip length in pixels, at least ``MIN_TORSO_SHARE`` of ``reference`` (pixels, e.g. the
    sequence's :func:`body_scale`), which also stands in when the neck or hip is absent."""
    kp = np.asarray(keypoints)
    if kp[NECK, 2] >= MIN_CONFIDENCE and kp[ROOT, 2] >= MIN_CONFIDENCE:
        return max(float(np.linalg.norm(kp[NECK, :2] - kp[ROOT, :2])), MIN_TORSO_SHARE * reference)
    return reference


def draw_person(mask: np.ndarray, xy: np.ndarray, present: np.ndarray, torso: float, margin: float) -> np.ndarray:
    """Fill (255) the region a person covers on ``mask`` (``[h, w]`` uint8, in place) and return it.

    Args:
        xy: ``[25, 2]`` joint positions in mask pixels; ``present``: ``[25]`` bool.
        torso: the person's torso length in mask pixels; limbs, head and hands are sized by it.
        margin: growth in mask pixels on every side.
    """
    pts = np.round(np.nan_to_num(xy) * (1 << _SHIFT)).astype(np.int64)
    limit = (1 << _SHIFT) * 4 * max(mask.shape)  # OpenCV's fixed-point maths overflows far off the canvas
    pts = np.clip(pts, -limit, limit)
    thickness = max(1, round(LIMB_WIDTH * torso + 2 * margin))
    for a, b in BODY25_LIMBS:
        if present[a] and present[b]:
            cv2.line(mask, tuple(map(int, pts[a])), tuple(map(int, pts[b])), 255, thickness, cv2.LINE_8, _SHIFT)
    for elbow, wrist in _FOREARMS:
        if present[elbow] and present[wrist]:
            direction = xy[wrist] - xy[elbow]
            tip = xy[wrist] + direction / max(float(np.linalg.norm(direction)), 1e-6) * HAND_LENGTH * torso
            tip = np.clip(np.round(tip * (1 << _SHIFT)), -limit, limit).astype(np.int64)
            cv2.line(mask, tuple(map(int, pts[wrist])), tuple(map(int, tip)), 255, thickness, cv2.LINE_8, _SHIFT)
    radius = (thickness // 2) << _SHIFT
    for j in np.flatnonzero(present):
        cv2.circle(mask, tuple(map(int, pts[j])), radius, 255, -1, cv2.LINE_8, _SHIFT)
    body = [j for j in _TORSO if present[j]]
    if len(body) >= 3:
        hull = cv2.convexHull(pts[body].astype(np.int32))
        cv2.fillConvexPoly(mask, hull, 255, cv2.LINE_8, _SHIFT)
    face = [j for j in _FACE if present[j]]
    if face:
        centre = np.round(xy[face].mean(axis=0) * (1 << _SHIFT)).astype(np.int64).clip(-limit, limit)
        cv2.circle(mask, tuple(map(int, centre)), round((HEAD_RADIUS * torso + margin) * (1 << _SHIFT)), 255, -1,
                   cv2.LINE_8, _SHIFT)
    return mask


def person_mask(keypoints: np.ndarray, width: int, height: int, reference: float, margin: float) -> np.ndarray:
    """``[height, width]`` bool: where the person of one ``[25, 3]`` pose (canvas pixels) stands, grown by
    ``margin`` torso lengths; ``reference`` is the sequence's torso length in pixels."""
    kp = np.asarray(keypoints, np.float32)
    torso = torso_length(kp, reference)
    mask = np.zeros((height, width), np.uint8)
    return draw_person(mask, kp[:, :2], kp[:, 2] >= MIN_CONFIDENCE, torso, margin * torso) > 0


def masks_file(framing: VideoFraming) -> str:
    return f"masks_{framing.out_width}x{framing.out_height}.npy"


def person_box(keypoints: np.ndarray, width: int, height: int) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)``: the square around one ``[25, 3]`` pose (canvas pixels) grown by :data:`CROP_GROWTH`,
    clipped to the ``width x height`` frame; None without any joint."""
    present = keypoints[:, 2] >= MIN_CONFIDENCE
    if not present.any():
        return None
    lo, hi = keypoints[present, :2].min(axis=0), keypoints[present, :2].max(axis=0)
    side = max(float((hi - lo).max()), 1.0) * (1 + 2 * CROP_GROWTH)
    cx, cy = (lo + hi) / 2
    x0, y0 = max(0, int(cx - side / 2)), max(0, int(cy - side / 2))
    x1, y1 = min(width, int(np.ceil(cx + side / 2))), min(height, int(np.ceil(cy + side / 2)))
    return (x0, y0, x1, y1) if x1 - x0 >= 8 and y1 - y0 >= 8 else None


class Segmenter:
    """BlazePose with segmentation on the consecutive person crops of one video (video mode: it tracks between
    calls, four times faster than searching every crop anew; the crops' size varies, so its mask smoothing, which
    needs one size, is off)."""

    def __init__(self) -> None:
        try:
            from mediapipe.python.solutions.pose import Pose
        except ImportError as e:
            raise DancesynthError("mediapipe is not installed; install it with "
                                  "`pip install --no-deps mediapipe==0.10.21` (see the Makefile).") from e
        self._graph = Pose(model_complexity=1, static_image_mode=False, enable_segmentation=True,
                           smooth_segmentation=False)

    def close(self) -> None:
        self._graph.close()

    def __call__(self, image: np.ndarray) -> np.ndarray | None:
        """``[h, w, 3]`` uint8 RGB -> ``[h, w]`` float32 person probability, or None when nobody is found."""
        result = self._graph.process(np.ascontiguousarray(image))
        return None if result.segmentation_mask is None else np.asarray(result.segmentation_mask, np.float32)


def frame_mask(segmenter: Segmenter, frame: np.ndarray, keypoints: np.ndarray, reference: float) -> np.ndarray:
    """``[H, W]`` bool: the person of one ``[25, 3]`` pose (canvas pixels) in one ``[H, W, 3]`` uint8 frame;
    ``reference`` is the video's torso length in pixels."""
    height, width = frame.shape[:2]
    near = person_mask(keypoints, width, height, reference, KEEP_MARGIN)
    box = person_box(keypoints, width, height)
    soft = None
    if box is not None:
        x0, y0, x1, y1 = box
        scale = SEGMENT_SIZE / max(x1 - x0, y1 - y0)
        crop = cv2.resize(frame[y0:y1, x0:x1], (max(1, round((x1 - x0) * scale)), max(1, round((y1 - y0) * scale))),
                          interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
        soft = segmenter(crop)
    if soft is None:
        return person_mask(keypoints, width, height, reference, FALLBACK_MARGIN)
    mask = np.zeros((height, width), bool)
    mask[y0:y1, x0:x1] = cv2.resize(soft, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR) >= MASK_THRESHOLD
    return mask & near


def framed_mask(mask: np.ndarray, framing: Framing) -> np.ndarray:
    """``[H, W]`` bool canvas mask -> ``[out_height, out_width]`` uint8 (0 or 255, resampled edges in between)."""
    return framing.image(mask.astype(np.uint8) * 255)


def cache_masks(video: Path, framing: VideoFraming, run_dir: Path, poses: PoseSequence,
                workers: int | None = None) -> np.ndarray:
    """Framed person masks ``[T, H, W]`` uint8 (memory-mapped; frame t framed as ``framing.frames(poses)[t]``),
    cached in ``run_dir`` keyed by the video's content, the framing and the poses. ``workers``: segmenting graphs
    run side by side (default: PyTorch's thread count, the cores this process may use)."""
    path = Path(run_dir) / masks_file(framing)
    boxes = framing.frames(poses)
    parts = frame_stretches(len(poses), workers or torch.get_num_threads())

    def write(tmp: Path) -> None:
        reference = body_scale(poses)
        out = np.lib.format.open_memmap(tmp, mode="w+", dtype=np.uint8,
                                        shape=(len(poses), framing.out_height, framing.out_width))
        counting = threading.Lock()

        def segment(part: range, out: np.ndarray) -> int:
            """Mask the frames of ``part`` into ``out``; the number of them the video holds."""
            segmenter, frames, count = Segmenter(), read_frames(video, part.start), 0
            try:
                for t, frame in zip(part, frames):
                    out[t] = framed_mask(frame_mask(segmenter, frame, poses.keypoints[t], reference), boxes[t])
                    count += 1
                    with counting:
                        progress.update()
            finally:
                frames.close()
                segmenter.close()
            return count

        with (native_logs_hidden_unless_debug(), track(total=len(poses), desc="person masks", unit="frame") as progress,
              ThreadPoolExecutor(len(parts)) as pool):
            count = sum(pool.map(segment, parts, [out] * len(parts)))
        out.flush()
        del out
        if count < len(poses):
            raise DancesynthError(f"{video} has {count} frames but the poses have {len(poses)}; "
                                  "pass the poses extracted from this video.")

    cache_file(path, Path(video), write, poses=poses_digest(poses), **framed_key(framing, boxes))
    return np.load(path, mmap_mode="r")
