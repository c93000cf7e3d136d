"""`dancesynth generate`: a dance (pose sequence) for a song, from a trained stage-1 run."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import add_beats_argument, existing_file, non_negative_int, output_file

NAME = "generate"
HELP = "generate a dance (BODY_25 pose sequence) for a song with a trained pose model"
DESCRIPTION = """\
Generate a dance for SONG (any audio file, any length) with a model trained by `dancesynth train-pose`, or
without --model the pose model shipped with dancesynth (Dance Revolution, trained on the built-in data).
The output .npz holds keypoints [T, 25, 3] (x, y in pixels of the training canvas, confidence 1), fps, width,
height, and the song's beats and downbeats in seconds (--beats picks the tracker); T = song length x fps.
Another --seed gives another dance (for stochastic methods).
--preview writes a skeleton video with the song as its soundtrack.

examples:
  dancesynth generate song.mp3 --out poses.npz
  dancesynth generate song.mp3 --model runs/dr --out poses.npz
  dancesynth generate song.mp3 --model runs/dr --out poses.npz --seed 3 --preview preview.mp4
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("song", type=existing_file, metavar="SONG",
                        help="audio file (mp3, wav, m4a, ... or a video's soundtrack)")
    parser.add_argument("--model", default=None, metavar="RUN_DIR",
                        help="run folder from dancesynth train-pose (default: the built-in Dance Revolution model)")
    parser.add_argument("--out", type=output_file, required=True, metavar="POSES.npz", help="output pose file")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="random seed of the dance (default 0)")
    parser.add_argument("--preview", type=output_file, metavar="VIDEO.mp4",
                        help="also write a skeleton preview video with the song")
    parser.add_argument("--precision", default="auto", choices=("auto", "fp32", "int8"),
                        help="decoder weights: int8 is ~3x faster on CPU; auto = int8 on CPU, fp32 on GPU")
    parser.add_argument("--no-beat-snap", dest="beat_snap", action="store_false",
                        help="keep the pose model's own timing instead of retiming its movement beats onto the "
                             "song's beats")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")
    add_beats_argument(parser)


def run(args: argparse.Namespace) -> None:
    from dancesynth.api import generate

    seq = generate(args.song, model=args.model, out=args.out, seed=args.seed, preview=args.preview,
                   beat_snap=args.beat_snap, precision=args.precision, device=args.device, beats=args.beats)
    logger.info(f"wrote {args.out}: {len(seq)} frames at {seq.fps:g} fps ({seq.duration:.1f} s), "
                f"{seq.width}x{seq.height} canvas" + (f"; preview {args.preview}" if args.preview else ""))
