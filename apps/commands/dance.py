"""`dancesynth dance`: song + trained pose and video models -> dancing video with the song's audio."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import (
    add_beats_argument,
    add_output_arguments,
    add_precision_argument,
    existing_file,
    non_negative_float,
    non_negative_int,
    output_file,
    output_folder,
    positive_float,
)
from stage2_video.presets import describe_presets, preset_names

NAME = "dance"
HELP = "make a video of the target person dancing to a song"
DESCRIPTION = """\
Generate a dance for SONG with a stage-1 pose model (the one shipped with dancesynth unless --pose-model is
given), resample it to the target video's frame rate, move it onto the target person's body (the person's own
bone lengths, then Everybody-Dance-Now normalisation) and render it with their appearance model, composited into
their own scene: the frame pipeline `dancesynth render` runs on a pose file. The output mp4 has the target
video's resolution (or --height) and frame rate and the song segment as AAC audio; picture and sound last the
segment's duration within one frame.

The person comes from --target VIDEO (one command: their appearance model is looked up in the cache, keyed by
the video's content and the preset, or trained now for --train-minutes; a later call with more minutes continues
it; a call with the same video and no more minutes starts rendering at once) or from --video-model RUN (a
run folder of `dancesynth train-video`).

SONG may be any audio FFmpeg reads (wav, mp3, ogg, m4a, flac, or the soundtrack of a video).

examples:
  dancesynth dance song.mp3 --target me.mp4 --out me_dancing.mp4
  dancesynth dance song.mp3 --target me.mp4 --train-minutes 60 --start 30 --duration 20 --out me.mp4
  dancesynth dance song.mp3 --video-model runs/me --pose-model runs/pose/dance_revolution \\
      --out me_dancing.mp4 --side-by-side compare.mp4
"""

logger = logging.getLogger(__name__)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("song", type=existing_file, metavar="SONG", help="the song (any FFmpeg-readable audio file)")
    p.add_argument("--out", type=output_file, required=True, metavar="OUT.mp4", help="the dancing video to write")
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--target", type=existing_file, metavar="VIDEO",
                     help="video of the person to animate (their appearance model is cached or trained now)")
    who.add_argument("--video-model", metavar="RUN", help="stage-2 run folder (from train-video)")
    p.add_argument("--train-minutes", type=non_negative_float, default=None, metavar="M",
                   help="with --target: minutes of appearance training in all (default 30); more continues "
                        "the cached model; 0 renders the person's own pixels warped onto the dance at once, "
                        "untrained")
    p.add_argument("--cache", type=output_folder, default=None, metavar="DIR",
                   help="with --target: appearance-model cache (default ~/.cache/dancesynth/appearance)")
    p.add_argument("--preset", choices=preset_names(auto=True), default=None,
                   help=f"with --target: the appearance model's preset (default auto); {describe_presets(auto=True)}")
    p.add_argument("--pose-model", default=None, metavar="RUN",
                   help="stage-1 run folder (from train-pose), or a folder of runs named by method "
                        "(default: the built-in Dance Revolution model)")
    p.add_argument("--method", default=None,
                   help="which run to use when --pose-model is a folder of runs (default dance_revolution)")
    p.add_argument("--seed", type=non_negative_int, default=0,
                   help="random seed: another seed gives another dance (default 0)")
    p.add_argument("--start", type=non_negative_float, default=0.0, metavar="S",
                   help="segment start in seconds (default 0)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="D",
                   help="segment length in seconds (default: to the end of the song)")
    add_output_arguments(p)
    add_precision_argument(p, "the appearance model's training (with --target) and rendering")
    p.add_argument("--no-beat-snap", dest="beat_snap", action="store_false",
                   help="keep the pose model's own timing instead of retiming its movement beats onto the "
                        "song's beats")
    p.add_argument("--device", default="auto", help="auto (GPU when available), cpu or cuda (default auto)")
    add_beats_argument(p)


def run(args: argparse.Namespace) -> None:
    from dancesynth.api import dance

    result = dance(args.song, out=args.out, target=args.target, video_model=args.video_model,
                   pose_model=args.pose_model, cache=args.cache, train_minutes=args.train_minutes,
                   preset=args.preset, method=args.method, seed=args.seed, start=args.start,
                   duration=args.duration, height=args.height, crop=args.crop,
                   skeleton_preview=args.skeleton_preview, side_by_side=args.side_by_side,
                   beat_snap=args.beat_snap, precision=args.precision, device=args.device,
                   beats=args.beats)
    logger.info(f"{len(result.poses)} frames at {result.poses.fps:g} fps with the appearance model "
                f"{result.video_model}; wrote " + ", ".join(map(str, result.written)))
