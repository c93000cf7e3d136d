"""Pose extraction speed and tracking accuracy on a synthetic moving-person clip (or on your own video).

No real video of a moving person is available offline, so the clip is the real astronaut photo
(``skimage.data.astronaut``) moved by a known affine motion (shift, scale 0.75-1.1, rotation +-12 degrees)
with a smaller second person in a corner; in the middle tenth of the clip the main person is hidden (an
occlusion). The reference pose is BlazePose on the unmoved photo mapped through the same affine, so the
error measures how consistently a method follows the person (crop tracking, jump rejection, gap filling,
smoothing), not BlazePose's absolute accuracy.

Rows: ``raw`` = BlazePose in video mode on the whole frame, no tracking (the baseline); the others = the
full :func:`stage2_video.extract.extract_poses` pipeline with each smoothing method. ``wrong person %`` =
frames whose median joint error exceeds half the person's torso length.

    .venv/bin/python benchmarks/bench_extract.py                      # 640x480, 90 frames
    .venv/bin/python benchmarks/bench_extract.py --video my_clip.mp4  # speed on your own video
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import skimage.data

from dancesynth.core.media import probe_video, read_frames, write_video
from stage2_video.extract import BlazePose, ExtractConfig, extract_poses
from stage2_video.smoothing import SmoothingConfig
from stage2_video.tracking import Box, torso


def affine_clip(frames: int, width: int, height: int) -> tuple[list[np.ndarray], np.ndarray]:
    """RGB frames and the ``[T, 2, 3]`` affine maps from photo pixels to frame pixels."""
    photo = skimage.data.astronaut()
    t = np.linspace(0, 1, frames)
    scale = 0.55 * height / 512 * (0.925 + 0.175 * np.sin(2 * np.pi * 1.5 * t))
    angle = 12 * np.sin(2 * np.pi * 2 * t)
    cx = width / 2 + 0.2 * width * np.sin(2 * np.pi * t)
    cy = height / 2 + 0.05 * height * np.cos(2 * np.pi * 3 * t)
    small = cv2.resize(photo, (height // 3, height // 3), interpolation=cv2.INTER_AREA)
    hidden = range(int(0.45 * frames), int(0.55 * frames))
    out, maps = [], []
    for i in range(frames):
        m = cv2.getRotationMatrix2D((256, 256), angle[i], scale[i])
        m[:, 2] += (cx[i] - 256, cy[i] - 256)
        frame = np.full((height, width, 3), 70, np.uint8)
        frame[height - small.shape[0]:, :small.shape[1]] = small
        if i not in hidden:
            warped = cv2.warpAffine(photo, m, (width, height))
            mask = cv2.warpAffine(np.ones(photo.shape[:2], np.uint8), m, (width, height)).astype(bool)
            frame[mask] = warped[mask]
        out.append(frame)
        maps.append(m)
    return out, np.stack(maps)


def raw_blazepose(video: Path) -> tuple[np.ndarray, np.ndarray]:
    """Whole-frame BlazePose in video mode: ``[T, 25, 3]`` poses (zeros when none) and ``[T]`` found flags."""
    info = probe_video(video)
    whole = Box(info.width / 2, info.height / 2, max(info.width, info.height))
    poses, found = [], []
    with BlazePose() as estimator:
        for frame in read_frames(video):
            pose = estimator.track(frame, whole)
            found.append(pose is not None)
            poses.append(np.zeros((25, 3), np.float32) if pose is None else pose)
    return np.stack(poses), np.array(found)


def accuracy(xy: np.ndarray, maps: np.ndarray) -> dict[str, float]:
    """Errors (pixels) of ``[T, 25, 2]`` poses against the photo's reference pose moved by ``maps``."""
    with BlazePose() as estimator:
        ref = estimator.detect(skimage.data.astronaut())
    present = ref[:, 2] > 0
    ref_xy = np.einsum("tij,kj->tki", maps, np.c_[ref[present, :2], np.ones(present.sum())])
    err = np.linalg.norm(xy[:, present] - ref_xy, axis=-1)
    torso_px = torso(ref)[1] * np.sqrt(np.abs(np.linalg.det(maps[:, :, :2])))
    return {"wrong person %": 100 * float(np.mean(np.median(err, axis=1) > 0.5 * torso_px)),
            "median err px": float(np.median(err)), "p95 err px": float(np.percentile(err, 95)),
            "jitter px": float(np.abs(np.diff(xy[:, present] - ref_xy, 2, axis=0)).mean())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=90)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--fps", type=float, default=30)
    parser.add_argument("--video", type=Path, help="time extraction on this video instead (no accuracy)")
    args = parser.parse_args()

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        video, maps = args.video, None
        if video is None:
            frames, maps = affine_clip(args.frames, args.width, args.height)
            video = Path(tmp) / "clip.mp4"
            write_video(video, frames, args.fps)
        raw_blazepose(video)  # warm-up: the first graph start loads the models from disk
        runs = {"raw": lambda: raw_blazepose(video)}
        for method in ("none", "savgol", "one-euro"):
            config = ExtractConfig(smoothing=SmoothingConfig(method), max_missing_fraction=1.0)
            runs[f"tracked+{method}"] = lambda c=config: (lambda r: (r.poses.keypoints, r.found))(
                extract_poses(video, c, progress=False))
        for name, fn in runs.items():
            start = time.perf_counter()
            keypoints, found = fn()
            row = {"method": name, "frames": len(found),
                   "ms/frame": 1000 * (time.perf_counter() - start) / len(found), "found %": 100 * found.mean()}
            if maps is not None:
                row |= accuracy(keypoints[..., :2], maps)
            rows.append(row)
    print(" | ".join(f"{k:>14}" for k in rows[0]))
    for row in rows:
        print(" | ".join(f"{v:>14.1f}" if isinstance(v, float) else f"{v!s:>14}" for v in row.values()))


if __name__ == "__main__":
    main()
