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

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import check_outputs
from dancesynth.core.media import SONG_SAMPLE_RATE, load_song
from dancesynth.core.skeleton import PoseSequence
from stage1_pose.beat_snap import DEFAULT_SNAP
from stage1_pose.beat_tracking.trackers import DEFAULT_BEAT_TRACKER
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


def dance(song: str | os.PathLike, out: str | os.PathLike, pose_model: str | os.PathLike | None = None,
          video_model: str | os.PathLike | None = None, target: str | os.PathLike | None = None,
          cache: str | os.PathLike | None = None, train_minutes: float | None = None, preset: str | None = None,
          method: str | None = None, seed: int = 0, start: float = 0.0, duration: float | None = None,
          skeleton_preview: str | os.PathLike | None = None, side_by_side: str | os.PathLike | None = None,
          crop: bool = False, height: int | None = None, beat_snap: bool = True, precision: str = "auto",
          device: str = "auto", progress: bool = True, beats: str = DEFAULT_BEAT_TRACKER) -> DanceResult:
    """Make ``out`` (mp4): the person of ``video_model`` (or of the video ``target``) dancing to ``song``.

    Args:
        pose_model: a stage-1 run (or folder of runs); None = the pose model shipped with the package.
        video_model, target: the appearance model's run folder, or a video of the person whose model is
            looked up in ``cache`` (default under the user's cache folder) and trained or continued until it
            has trained ``train_minutes`` in all (default 30), at ``preset`` (default ``auto``: 256 px where the
            hardware makes it affordable, else 128). Exactly one of the two.
        start, duration: the song segment in seconds (duration None = to the end).
        crop: write the model's crop around the person instead of the whole scene.
        height: output height in pixels (aspect kept); default the target video's own.
        skeleton_preview: optional mp4 of the dance as a skeleton (same size, with the song).
        side_by_side: optional mp4 of skeleton | generated person (with the song).
        beat_snap: retime the dance onto the song's beats (:mod:`stage1_pose.beat_snap`).
        beats: the beat tracker, ``learned`` or ``dsp`` (:func:`stage1_pose.beats.song_beats`).
        precision: stage-2 arithmetic, ``auto`` (from the hardware), ``fp32`` or ``bf16``.
    """
    if (video_model is None) == (target is None):
        raise DancesynthError("Give the person to animate either as --target VIDEO or as --video-model RUN, "
                              "not both and not neither.")
    if video_model is not None and (cache, train_minutes, preset) != (None, None, None):
        raise DancesynthError("--train-minutes, --cache and --preset apply to --target only; drop them when "
                              "using --video-model.")
    check_output_options(crop, height)
    # Everything fast to check comes before a training that may take minutes.
    check_outputs({"dance video": out, "skeleton preview": skeleton_preview, "side-by-side video": side_by_side},
                  {"song": song, "target video": target, "appearance model": video_model, "pose model": pose_model})
    segment = song_segment(load_song(song, SONG_SAMPLE_RATE), SONG_SAMPLE_RATE, start, duration)
    pose_model_loaded = load_pose_model(find_pose_run(pose_model, method), device)
    if target is not None:
        video_model = appearance_model_for(target, DEFAULT_TRAIN_MINUTES if train_minutes is None else train_minutes,
                                           resolve_preset(preset, device, precision), cache, device, precision)
    poses = generate_dance(pose_model_loaded, segment, SONG_SAMPLE_RATE, seed=seed,
                           snap=DEFAULT_SNAP if beat_snap else None, tracker=beats)
    appearance = load_appearance_model(video_model, device, precision=precision)
    rendered = render_video(poses, appearance, out, audio=segment, audio_sr=SONG_SAMPLE_RATE, crop=crop,
                            height=height, skeleton_preview=skeleton_preview, side_by_side=side_by_side,
                            progress=progress)
    return DanceResult(rendered.poses, rendered.written, Path(video_model), rendered.seconds)
