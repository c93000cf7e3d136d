"""Draw BODY_25 skeletons in OpenPose's colours, onto images or as a preview video."""

from __future__ import annotations

import os
from collections.abc import Iterator

import cv2
import numpy as np

from dancesynth.core.media import VideoWriter
from dancesynth.core.skeleton import BODY25_COLORS, BODY25_LIMBS, PoseSequence

# Sub-pixel precision for OpenCV's drawing calls: coordinates are passed multiplied by 2**_SHIFT.
_SHIFT = 4


def line_width(height: int, width: int) -> int:
    """Limb width in pixels for an image of ``height`` x ``width``: about 1/120 of its smaller side."""
    return max(1, round(min(height, width) / 120))


def draw_pose(image: np.ndarray, keypoints: np.ndarray, thickness: int | None = None,
              min_confidence: float = 0.05) -> np.ndarray:
    """Draw one BODY_25 pose on an RGB uint8 ``[H, W, 3]`` image (in place) and return it.

    Args:
        image: the canvas; ``keypoints`` are in its pixel coordinates.
        keypoints: ``[25, 3]`` x, y (pixels), confidence.
        thickness: limb width in pixels (default :func:`line_width`); joints are circles of the same diameter.
        min_confidence: joints below it are absent, and so are limbs touching them.
    """
    kp = np.asarray(keypoints, dtype=np.float64)
    h, w = image.shape[:2]
    width = line_width(h, w) if thickness is None else max(1, int(thickness))
    present = (kp[:, 2] >= min_confidence) & np.isfinite(kp[:, :2]).all(axis=1)
    fixed = np.round(np.nan_to_num(kp[:, :2]) * (1 << _SHIFT)).astype(np.int64)
    # Far-off coordinates overflow OpenCV's fixed-point maths; anything beyond a canvas-size margin is clipped.
    limit = (1 << _SHIFT) * 4 * max(h, w)
    fixed = np.clip(fixed, -limit, limit)
    for a, b in BODY25_LIMBS:
        if present[a] and present[b]:
            cv2.line(image, tuple(map(int, fixed[a])), tuple(map(int, fixed[b])), BODY25_COLORS[b],
                     thickness=width, lineType=cv2.LINE_AA, shift=_SHIFT)
    radius = max(1, width) << _SHIFT
    for j in np.flatnonzero(present):
        cv2.circle(image, tuple(map(int, fixed[j])), int(radius * 0.6), BODY25_COLORS[j], thickness=-1,
                   lineType=cv2.LINE_AA, shift=_SHIFT)
    return image


def fit_to_canvas(src_width: int, src_height: int, width: int, height: int) -> tuple[float, float, float]:
    """Scale and offsets ``(s, dx, dy)`` mapping a ``src`` canvas into ``width`` x ``height`` keeping the aspect
    ratio (centred, letterboxed): ``out = s * in + (dx, dy)`` in pixels."""
    s = min(width / src_width, height / src_height)
    return s, (width - s * src_width) / 2.0, (height - s * src_height) / 2.0


def skeleton_frames(seq: PoseSequence, width: int | None = None, height: int | None = None,
                    background: tuple[int, int, int] = (0, 0, 0), thickness: int | None = None) -> Iterator[np.ndarray]:
    """One RGB uint8 ``[height, width, 3]`` skeleton image per pose frame (streamed).

    The output size defaults to the pose canvas; another size scales the canvas into it keeping the aspect
    ratio (letterboxed, centred). Only ``width`` or only ``height`` keeps the canvas aspect ratio.
    """
    if width is None and height is None:
        width, height = seq.width, seq.height
    elif height is None:
        height = max(1, round(width * seq.height / seq.width))
    elif width is None:
        width = max(1, round(height * seq.width / seq.height))
    s, dx, dy = fit_to_canvas(seq.width, seq.height, width, height)
    for kp in seq.keypoints:
        image = np.empty((height, width, 3), np.uint8)
        image[:] = background
        scaled = kp.copy()
        scaled[:, :2] = kp[:, :2] * s + (dx, dy)
        yield draw_pose(image, scaled, thickness=thickness)


def write_skeleton_video(seq: PoseSequence, path: str | os.PathLike, audio: np.ndarray | None = None,
                         audio_sr: int | None = None, size: tuple[int, int] | None = None) -> None:
    """Write a skeleton-only preview mp4 at the sequence's fps, optionally with the song.

    Args:
        size: ``(width, height)`` in pixels; default the pose canvas.
        audio: mono ``[N]`` samples at ``audio_sr`` Hz, cut or padded to the video's duration.
    """
    width, height = size if size is not None else (seq.width, seq.height)
    with VideoWriter(path, seq.fps, width, height, audio=audio, audio_sr=audio_sr) as writer:
        for frame in skeleton_frames(seq, width, height):
            writer.write(frame)
