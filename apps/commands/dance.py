"""`dancesynth dance`: song + trained pose and video models -> dancing video with the song's audio."""

from __future__ import annotations

import argparse

from apps.pipeline import dance

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


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("song", metavar="SONG", help="the song (any FFmpeg-readable audio file)")
    p.add_argument("--pose-model", required=True, metavar="RUN",
                   help="stage-1 run folder (from train-pose), or a folder of runs named by method")
    p.add_argument("--video-model", required=True, metavar="RUN", help="stage-2 run folder (from train-video)")
    p.add_argument("--out", required=True, metavar="OUT.mp4", help="the dancing video to write")
    p.add_argument("--method", default=None,
                   help="which run to use when --pose-model is a folder of runs (default dance_revolution)")
    p.add_argument("--seed", type=int, default=0, help="random seed: another seed gives another dance (default 0)")
    p.add_argument("--start", type=float, default=0.0, metavar="S", help="segment start in seconds (default 0)")
    p.add_argument("--duration", type=float, default=None, metavar="D",
                   help="segment length in seconds (default: to the end of the song)")
    p.add_argument("--skeleton-preview", default=None, metavar="PATH", help="also write the skeleton as a video")
    p.add_argument("--side-by-side", default=None, metavar="PATH",
                   help="also write skeleton | generated person side by side")
    p.add_argument("--device", default="auto", help="auto (GPU when available), cpu or cuda (default auto)")


def run(args: argparse.Namespace) -> None:
    result = dance(args.song, args.pose_model, args.video_model, args.out, method=args.method, seed=args.seed,
                   start=args.start, duration=args.duration, skeleton_preview=args.skeleton_preview,
                   side_by_side=args.side_by_side, device=args.device)
    print(f"{len(result.poses)} frames at {result.poses.fps:g} fps; wrote " + ", ".join(map(str, result.written)))
