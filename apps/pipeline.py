"""Song + trained models -> dancing video: the composition behind `dancesynth dance`.

Data path (see docs/architecture.md): decode the song, cut the requested segment, find (or train) the target's
appearance model, stage 1 generates a dance at the pose model's fps, and stage 2's frame pipeline
(:func:`stage2_video.render.render_video`, the one `dancesynth render` runs on a pose file) resamples it to the
target video's fps (C1 interpolation), gives it the target's bone lengths, normalises it onto the target's body
(Everybody Dance Now), renders model-resolution crops, composites them into the target's scene and streams the
frames into the H.264 encoder with the segment's audio. Every output is written under a temporary name and
renamed when complete.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from apps.requests import DanceRequest
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import check_outputs, check_video_names
from dancesynth.core.media import SONG_SAMPLE_RATE, load_song
from dancesynth.core.skeleton import PoseSequence
from stage1_pose.beat_snap import DEFAULT_SNAP
from stage1_pose.generate import generate_dance, load_pose_model
from stage1_pose.pretrained import DEFAULT_POSE_MODEL
from stage2_video.model_cache import appearance_model_for
from stage2_video.presets import resolve_preset
from stage2_video.render import check_output_options, load_appearance_model, render_video

# Minutes of appearance training a --target gets in all unless told otherwise.
DEFAULT_TRAIN_MINUTES = 30.0
# Method tried first when a folder of several pose-model runs is given without --method.
DEFAULT_METHOD = "dance_revolution"


def find_pose_run(path: str | os.PathLike | None, method: str | None = None) -> Path:
    """The stage-1 run folder to use.

    ``path`` is either a run folder (it holds ``latest.json``) or a folder of runs named after their method
    (as ``dancesynth demo`` writes them); ``method`` picks one of the latter, default ``dance_revolution``
    or the only run present. None = the pose model shipped with the package (Dance Revolution).
    """
    if path is None:
        if method not in (None, DEFAULT_METHOD):
            raise DancesynthError(f"The built-in pose model is {DEFAULT_METHOD}; for {method}, train one with "
                                  "`dancesynth train-pose` and pass it with --pose-model.")
        return DEFAULT_POSE_MODEL
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

    poses: PoseSequence  # the generated dance at the output fps, on the target's canvas (pixels)
    written: list[Path] = field(default_factory=list)
    video_model: Path | None = None  # the appearance model used (with --target: its cache entry)
    # wall seconds of the frame loop (rendering, compositing, encoding every output), without loading and training
    render_seconds: float = 0.0


def dance(request: DanceRequest, progress: bool = True) -> DanceResult:
    """Make ``request.out`` (mp4): the person of ``request.video_model`` (or of the video ``request.target``)
    dancing to ``request.song``; the fields mean what :func:`dancesynth.api.dance` says. ``progress``: report the
    frame loop's progress."""
    song, target, video_model, device, precision = (request.song, request.target, request.video_model,
                                                    request.device, request.precision)
    if (video_model is None) == (target is None):
        raise DancesynthError("Give the person to animate either as --target VIDEO or as --video-model RUN, "
                              "not both and not neither.")
    if video_model is not None and (request.cache, request.train_minutes, request.preset) != (None, None, None):
        raise DancesynthError("--train-minutes, --cache and --preset apply to --target only; drop them when "
                              "using --video-model.")
    check_output_options(request.crop, request.height)
    outputs = {"dance video": request.out, "skeleton preview": request.skeleton_preview,
               "side-by-side video": request.side_by_side}
    # Everything fast to check comes before a training that may take minutes.
    check_video_names(outputs)
    check_outputs(outputs, {"song": song, "target video": target, "appearance model": video_model,
                            "pose model": request.pose_model})
    segment = song_segment(load_song(song, SONG_SAMPLE_RATE), SONG_SAMPLE_RATE, request.start, request.duration)
    pose_model = load_pose_model(find_pose_run(request.pose_model, request.method), device)
    if target is not None:
        minutes = DEFAULT_TRAIN_MINUTES if request.train_minutes is None else request.train_minutes
        video_model = appearance_model_for(target, minutes, resolve_preset(request.preset, device, precision),
                                           request.cache, device, precision)
    poses = generate_dance(pose_model, segment, SONG_SAMPLE_RATE, seed=request.seed,
                           snap=DEFAULT_SNAP if request.beat_snap else None, tracker=request.beats)
    appearance = load_appearance_model(video_model, device, precision=precision)
    rendered = render_video(poses, appearance, request.out, audio=segment, audio_sr=SONG_SAMPLE_RATE,
                            crop=request.crop, height=request.height, skeleton_preview=request.skeleton_preview,
                            side_by_side=request.side_by_side, progress=progress)
    return DanceResult(rendered.poses, rendered.written, Path(video_model), rendered.seconds)
