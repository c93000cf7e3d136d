"""A folder of real dance videos -> a stage-1 dataset: the composition behind `dancesynth prepare`.

Each video's dancer is found with the stage-2 pose extractor (BlazePose, one tracked person), its soundtrack is
decoded, and both are cut into clips of about ``clip_seconds`` seconds that are appended to the dataset folder
with :func:`stage1_pose.data.importers.add_clip_samples` (15 fps poses, 22050 Hz audio, tracked beats). The
style of a video is the name of its sub-folder. All clips of one video share one song id, hence one
train/val/test split, so no song is both trained on and evaluated on.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import load_song
from dancesynth.core.skeleton import PoseSequence
from stage1_pose.beat_tracking.trackers import DEFAULT_BEAT_TRACKER
from stage1_pose.data.importers import add_clip_samples, song_id
from stage1_pose.data.layout import MANIFEST, SAMPLE_RATE, read_manifest

logger = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".mov", ".m4v", ".mkv", ".avi", ".webm")


@dataclass
class PrepareReport:
    """What :func:`prepare_videos` did: clip ids added, and videos skipped with the reason."""

    added: list[str] = field(default_factory=list)
    already_there: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)


def find_videos(videos_dir: str | os.PathLike, default_style: str) -> list[tuple[Path, str]]:
    """``(video, style)`` for every video under ``videos_dir``, sorted by path.

    A video's style is its first sub-folder under ``videos_dir`` (``VIDEOS/salsa/a.mp4`` -> ``salsa``); videos
    directly in ``videos_dir`` get ``default_style``.
    """
    root = Path(videos_dir)
    if not root.is_dir():
        raise DancesynthError(f"{root} is not a folder; pass the folder that holds your dance videos.")
    videos = sorted(p for p in root.rglob("*") if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES)
    if not videos:
        raise DancesynthError(f"{root} holds no videos ({', '.join(VIDEO_SUFFIXES)}); put your dance videos there, "
                              "one sub-folder per style.")
    return [(v, v.relative_to(root).parts[0] if len(v.relative_to(root).parts) > 1 else default_style)
            for v in videos]


def clip_bounds(seconds: float, clip_seconds: float) -> list[tuple[float, float]]:
    """Cut ``seconds`` into the whole number of equal clips closest to ``clip_seconds`` each (at least one)."""
    count = max(1, int(round(seconds / clip_seconds)))
    edges = np.linspace(0.0, seconds, count + 1)
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def _clip_id(style: str, video: Path, index: int) -> str:
    return f"{style}_{video.stem}_{index:03d}"


def _blazepose_dancer(video: Path, progress: bool) -> PoseSequence:
    from stage2_video.extract import extract_poses  # needs mediapipe: imported only when used

    return extract_poses(video, progress=progress).poses


def prepare_videos(videos_dir: str | os.PathLike, out_dir: str | os.PathLike, clip_seconds: float = 60.0,
                   default_style: str = "dance", extract: Callable[[Path], PoseSequence] | None = None,
                   progress: bool = True, tracker: str = DEFAULT_BEAT_TRACKER) -> PrepareReport:
    """Add every video of ``videos_dir`` to the dataset folder ``out_dir`` (created when new).

    Videos whose clips are all in the dataset already are left alone, so the command can be re-run after adding
    videos (or after an interruption). A video without a soundtrack, without one clearly visible person,
    unreadable, or a link to a file outside ``videos_dir`` is skipped with the reason; the others are still added.

    Args:
        clip_seconds: target clip length in seconds (a video is cut into equal parts of about this length).
        default_style: style of the videos directly in ``videos_dir``.
        extract: ``video path -> PoseSequence`` (default: :func:`stage2_video.extract.extract_poses`).
        tracker: the beat tracker, ``combined``, ``learned`` or ``dsp`` (:func:`stage1_pose.beats.song_beats`).
    """
    if clip_seconds < 2:
        raise DancesynthError(f"--clip-seconds must be at least 2 s, got {clip_seconds:g}.")
    extract = extract or (lambda video: _blazepose_dancer(video, progress))
    videos = find_videos(videos_dir, default_style)
    inside = Path(videos_dir).resolve()
    existing = {c.id for c in read_manifest(out_dir).clips} if (Path(out_dir) / MANIFEST).exists() else set()
    report = PrepareReport()
    for number, (video, style) in enumerate(videos, start=1):
        if progress:
            logger.info(f"[{number}/{len(videos)}] {video} (style {style})")
        try:
            if not video.resolve().is_relative_to(inside):
                raise DancesynthError(f"{video} is a link to a file outside {videos_dir}; copy the video into "
                                      "the folder to use it.")
            samples = load_song(video, SAMPLE_RATE)
            bounds = clip_bounds(len(samples) / SAMPLE_RATE, clip_seconds)
            ids = [_clip_id(style, video, i) for i in range(len(bounds))]
            if all(i in existing for i in ids):
                report.already_there.extend(ids)
                continue
            poses = extract(video)
            song = song_id(samples)
            for clip_id, (start, stop) in zip(ids, bounds):
                if clip_id in existing:
                    continue
                first, last = int(round(start * poses.fps)), int(round(stop * poses.fps))
                part = samples[int(round(start * SAMPLE_RATE)):int(round(stop * SAMPLE_RATE))]
                add_clip_samples(out_dir, poses.slice_frames(first, min(last, len(poses))), part, style, clip_id,
                                 song=song, tracker=tracker)
                report.added.append(clip_id)
        except DancesynthError as e:
            report.skipped[str(video)] = str(e)
            if progress:
                logger.info(f"  skipped: {e}")
    return report
