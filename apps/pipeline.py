"""Song + trained models -> dancing video: the composition behind `dancesynth dance`.

Data path (see docs/architecture.md): decode the song, cut the requested segment, stage 1 generates a dance at
the pose model's fps, the dance is resampled to the target video's fps and normalised onto the target's
body (Everybody Dance Now), stage 2 renders frames that stream into the H.264 encoder, and the segment's
audio is muxed in. Every output is written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.media import SONG_SAMPLE_RATE, VideoWriter, load_song
from dancesynth.core.progress import track
from dancesynth.core.skeleton import PoseSequence, resample
from stage1_pose.generate import generate_dance, load_pose_model
from stage2_video.framing import label_map
from stage2_video.render import load_appearance_model, render_frames, target_poses

# Method tried first when a folder of several pose-model runs is given without --method.
DEFAULT_METHOD = "dance_revolution"


def find_pose_run(path: str | os.PathLike, method: str | None = None) -> Path:
    """The stage-1 run folder to use.

    ``path`` is either a run folder (it holds ``latest.json``) or a folder of runs named after their method
    (as ``dancesynth demo`` writes them); ``method`` picks one of the latter, default ``dance_revolution``
    or the only run present.
    """
    path = Path(path)
    if (path / "latest.json").is_file():
        return path
    runs = sorted(p.name for p in path.iterdir() if (p / "latest.json").is_file()) if path.is_dir() else []
    if not runs:
        raise DancesynthError(f"{path} holds no trained pose model; train one with `dancesynth train-pose` "
                              "and pass its --out folder.")
    wanted = method or (DEFAULT_METHOD if DEFAULT_METHOD in runs or len(runs) > 1 else runs[0])
    if wanted not in runs:
        raise DancesynthError(f"{path} has no run for method {wanted!r}; available: {', '.join(runs)}.")
    return path / wanted


def song_segment(samples: np.ndarray, sr: int, start: float = 0.0, duration: float | None = None,
                 min_seconds: float = 1.0) -> np.ndarray:
    """Samples ``[start, start + duration)`` seconds of the song (to its end when ``duration`` is None); the
    segment must last at least ``min_seconds``."""
    total = len(samples) / sr
    if start < 0 or start >= total:
        raise DancesynthError(f"--start {start:g} s is outside the song, which lasts {total:.1f} s; "
                              "choose a start inside it.")
    if duration is not None and duration <= 0:
        raise DancesynthError(f"--duration must be positive, got {duration:g} s.")
    if total - start < min_seconds:
        raise DancesynthError(f"--start {start:g} s is too close to the end of the song, which lasts {total:.1f} s; "
                              f"choose a start at least {min_seconds:g} s before its end.")
    if duration is not None and duration < min_seconds:
        raise DancesynthError(f"--duration {duration:g} s is too short; choose at least {min_seconds:g} s.")
    stop = len(samples) if duration is None else min(len(samples), int(round((start + duration) * sr)))
    return samples[int(round(start * sr)):stop]


@dataclass
class DanceResult:
    """What :func:`dance` produced."""

    poses: PoseSequence  # the generated dance at the output fps, on the target's canvas
    written: list[Path] = field(default_factory=list)


def dance(song: str | os.PathLike, pose_model: str | os.PathLike, video_model: str | os.PathLike,
          out: str | os.PathLike, method: str | None = None, seed: int = 0, start: float = 0.0,
          duration: float | None = None, skeleton_preview: str | os.PathLike | None = None,
          side_by_side: str | os.PathLike | None = None, device: str = "auto", progress: bool = True) -> DanceResult:
    """Make ``out`` (mp4): the target person of ``video_model`` dancing to ``song``'s segment.

    Args:
        start, duration: the song segment in seconds (duration None = to the end).
        skeleton_preview: optional mp4 of the dance as a skeleton (target canvas, with the song).
        side_by_side: optional mp4 of skeleton input | generated person, with the song.
    """
    # The song is decoded once; the same samples become the output's AAC track.
    segment = song_segment(load_song(song, SONG_SAMPLE_RATE), SONG_SAMPLE_RATE, start, duration)
    pose_model_loaded = load_pose_model(find_pose_run(pose_model, method), device)
    poses = generate_dance(pose_model_loaded, segment, SONG_SAMPLE_RATE, seed=seed)
    appearance = load_appearance_model(video_model, device)
    # The video has the target's frame rate; the dance keeps its timing (resampled in seconds, not frames).
    poses = target_poses(appearance, resample(poses, appearance.fps))
    width, height = appearance.config.width, appearance.config.height
    outputs = [(Path(out), width)]
    if skeleton_preview is not None:
        outputs.append((Path(skeleton_preview), width))
    if side_by_side is not None:
        outputs.append((Path(side_by_side), 2 * width))
    # One generator pass feeds every output, so the extra videos cost encoding only.
    with contextlib.ExitStack() as stack:
        writers = [stack.enter_context(VideoWriter(path, poses.fps, w, height, audio=segment,
                                                     audio_sr=SONG_SAMPLE_RATE))
                   for path, w in outputs]
        rendered = render_frames(appearance, poses, normalize=False)
        for keypoints, frame in track(zip(poses.keypoints, rendered), total=len(poses), desc="rendering",
                                     unit="frame", disable=not progress):
            label = label_map(keypoints, appearance.framing) if len(writers) > 1 else None
            writers[0].write(frame)
            if skeleton_preview is not None:
                writers[1].write(label)
            if side_by_side is not None:
                writers[-1].write(np.concatenate([label, frame], axis=1))
    return DanceResult(poses, [path for path, _ in outputs])
