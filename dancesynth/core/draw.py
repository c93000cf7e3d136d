"""Draw BODY_25 skeletons in OpenPose's colours, onto images, as a preview video or as a labelled grid of dances."""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence

import cv2
import numpy as np

from dancesynth.core.media import VideoWriter, write_video
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


# Beat flash of the grid video: a white border this many frames long starting on each beat (~0.13 s at 15 fps).
FLASH_FRAMES = 2
_LABEL_FONT = cv2.FONT_HERSHEY_SIMPLEX


def beat_flash_frames(beats: np.ndarray, fps: float, num_frames: int, flash_frames: int = FLASH_FRAMES) -> np.ndarray:
    """``[num_frames]`` bool: True on the ``flash_frames`` frames starting at each beat (seconds -> nearest frame)."""
    flash = np.zeros(num_frames, bool)
    for start in np.round(np.asarray(beats, np.float64) * fps).astype(np.int64):
        flash[max(start, 0):max(start + flash_frames, 0)] = True
    return flash


def _draw_label(tile: np.ndarray, text: str, margin: int) -> None:
    """White text with a black outline in the top-left corner of ``tile`` (in place); a label too long for the
    tile is cut and ends in ``..`` (shrinking it instead would make it unreadable)."""
    scale = max(0.4, tile.shape[1] / 700)
    thickness = max(1, round(scale * 1.5))

    def fits(s: str) -> bool:
        return cv2.getTextSize(s, _LABEL_FONT, scale, thickness)[0][0] <= tile.shape[1] - 2 * margin

    if not fits(text):
        text = next((text[:n] + ".." for n in range(len(text) - 1, 0, -1) if fits(text[:n] + "..")), text[:1])
    origin = (margin, margin + cv2.getTextSize(text, _LABEL_FONT, scale, thickness)[0][1])
    cv2.putText(tile, text, origin, _LABEL_FONT, scale, (0, 0, 0), thickness + 2, cv2.LINE_AA)
    cv2.putText(tile, text, origin, _LABEL_FONT, scale, (255, 255, 255), thickness, cv2.LINE_AA)


def grid_frames(dances: Sequence[PoseSequence], labels: Sequence[str], beats: np.ndarray | None = None,
                columns: int = 3, width: int = 1280, flash_frames: int = FLASH_FRAMES) -> Iterator[np.ndarray]:
    """Several dances side by side: one RGB uint8 frame per pose frame, tiled row by row (streamed).

    Each tile shows one dance's skeleton (its canvas scaled in, aspect ratio of the first dance's canvas) with
    its label in the top-left corner; on the ``flash_frames`` frames starting at each of ``beats`` (seconds)
    every tile gets a white border. Tiles are ``width // columns`` pixels wide (rounded down to even), so the
    frame is at most ``width`` wide; empty tiles of the last row stay black. The video lasts as long as the
    shortest dance, at the first dance's fps.
    """
    if not dances or len(dances) != len(labels):
        raise ValueError(f"need one label per dance and at least one dance, got {len(dances)} and {len(labels)}")
    columns = min(columns, len(dances))
    rows = -(-len(dances) // columns)
    tile_w = (width // columns) & ~1
    tile_h = max(2, round(tile_w * dances[0].height / dances[0].width / 2) * 2)
    border = max(2, tile_w // 50)
    num_frames = min(len(d) for d in dances)
    flash = beat_flash_frames(np.zeros(0) if beats is None else beats, dances[0].fps, num_frames, flash_frames)
    tiles = [skeleton_frames(d, tile_w, tile_h) for d in dances]
    for t in range(num_frames):
        frame = np.zeros((rows * tile_h, columns * tile_w, 3), np.uint8)
        for k, (stream, label) in enumerate(zip(tiles, labels)):
            tile = frame[(k // columns) * tile_h:(k // columns + 1) * tile_h,
                         (k % columns) * tile_w:(k % columns + 1) * tile_w]
            tile[:] = next(stream)
            if flash[t]:
                cv2.rectangle(tile, (0, 0), (tile_w - 1, tile_h - 1), (255, 255, 255), thickness=2 * border)
            _draw_label(tile, label, margin=border + 4)
        yield frame


def write_grid_video(dances: Sequence[PoseSequence], labels: Sequence[str], path: str | os.PathLike,
                     beats: np.ndarray | None = None, audio: np.ndarray | None = None, audio_sr: int | None = None,
                     columns: int = 3, width: int = 1280) -> None:
    """Write :func:`grid_frames` as an mp4 at the first dance's fps, optionally with the song.

    Args:
        beats: music beats in seconds, shown as a flash of every tile's border.
        audio: mono ``[N]`` samples at ``audio_sr`` Hz, cut or padded to the video's duration.
    """
    write_video(path, grid_frames(dances, labels, beats, columns, width), dances[0].fps, audio=audio,
                audio_sr=audio_sr)
