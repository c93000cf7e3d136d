"""`dancesynth dance`: song + trained pose and video models -> dancing video with the song's audio."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import existing_file, non_negative_float, non_negative_int, output_file, positive_float

NAME = "dance"
HELP = "make a video of the target person dancing to a song"
DESCRIPTION = """\
Generate a dance for SONG with a stage-1 pose model, move it onto the target person's body
(Everybody-Dance-Now normalisation) and render it with their stage-2 appearance model. The output mp4 has
the target model's resolution and frame rate and the song segment as AAC audio; picture and sound last
the segment's duration within one frame.

SONG may be any audio FFmpeg reads (wav, mp3, ogg, m4a, flac, or the soundtrack of a video).

example:
  dancesynth dance song.mp3 --pose-model runs/pose/dance_revolution --video-model runs/me \\
      --out me_dancing.mp4 --start 30 --duration 20 --side-by-side compare.mp4
"""

logger = logging.getLogger(__name__)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("song", type=existing_file, metavar="SONG", help="the song (any FFmpeg-readable audio file)")
    p.add_argument("--pose-model", required=True, metavar="RUN",
                   help="stage-1 run folder (from train-pose), or a folder of runs named by method")
    p.add_argument("--video-model", required=True, metavar="RUN", help="stage-2 run folder (from train-video)")
    p.add_argument("--out", type=output_file, required=True, metavar="OUT.mp4", help="the dancing video to write")
    p.add_argument("--method", default=None,
                   help="which run to use when --pose-model is a folder of runs (default dance_revolution)")
    p.add_argument("--seed", type=non_negative_int, default=0,
                   help="random seed: another seed gives another dance (default 0)")
    p.add_argument("--start", type=non_negative_float, default=0.0, metavar="S",
                   help="segment start in seconds (default 0)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="D",
                   help="segment length in seconds (default: to the end of the song)")
    p.add_argument("--skeleton-preview", type=output_file, default=None, metavar="PATH",
                   help="also write the skeleton as a video")
    p.add_argument("--side-by-side", type=output_file, default=None, metavar="PATH",
                   help="also write skeleton | generated person side by side")
    p.add_argument("--device", default="auto", help="auto (GPU when available), cpu or cuda (default auto)")


def run(args: argparse.Namespace) -> None:
    from dancesynth.api import dance

    result = dance(args.song, pose_model=args.pose_model, video_model=args.video_model, out=args.out,
                   method=args.method, seed=args.seed, start=args.start, duration=args.duration,
                   skeleton_preview=args.skeleton_preview, side_by_side=args.side_by_side, device=args.device)
    logger.info(f"{len(result.poses)} frames at {result.poses.fps:g} fps; wrote "
                + ", ".join(map(str, result.written)))
