"""`dancesynth render`: pose sequence -> video of the target person."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import add_output_arguments, add_precision_argument, existing_file, output_file, positive_int

NAME = "render"
HELP = "render a pose sequence as a video of the person a train-video model learned"
DESCRIPTION = """\
Render POSES (a dancesynth .npz pose file, e.g. from `dancesynth generate` or `dancesynth extract-poses`) with
an appearance model trained by `dancesynth train-video`, through the frame pipeline of `dancesynth dance`: the
poses are resampled to the target video's frame rate, given the target person's own bone lengths, then
normalised onto their body (Everybody Dance Now: scale and position from ankle heights and body size;
--no-normalize skips both, for poses already on the target's canvas), rendered and composited into the target's
scene. The output mp4 has the target video's resolution (or --height; --crop writes the model's crop) and frame
rate; --audio muxes a song (cut to the video's length).

examples:
  dancesynth render dance.npz --model runs/person --out dance.mp4 --audio song.mp3
  dancesynth render dance.npz --model runs/person --out crop.mp4 --crop --side-by-side compare.mp4
  dancesynth render runs/person/poses.npz --model runs/person --out replay.mp4 --no-normalize
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("poses", type=existing_file, metavar="POSES", help="pose file (.npz, BODY_25)")
    parser.add_argument("--model", required=True, metavar="RUN_DIR", help="run folder written by train-video")
    parser.add_argument("--out", type=output_file, required=True, metavar="VIDEO.mp4", help="output video")
    parser.add_argument("--audio", type=existing_file, metavar="SONG", help="audio file to mux (any FFmpeg format)")
    parser.add_argument("--no-normalize", action="store_true",
                        help="use the poses as they are, without retargeting or normalisation (target canvas)")
    add_output_arguments(parser)
    parser.add_argument("--no-optimize", action="store_true", help="plain PyTorch forward (slower, for debugging)")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")
    add_precision_argument(parser, "rendering")
    parser.add_argument("--threads", type=positive_int, metavar="N",
                        help="CPU threads for torch (default: torch's choice; 1 is faster on a busy machine)")


def run(args: argparse.Namespace) -> None:
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    from dancesynth.api import render

    result = render(args.poses, model=args.model, out=args.out, audio=args.audio, normalize=not args.no_normalize,
                    height=args.height, crop=args.crop, skeleton_preview=args.skeleton_preview,
                    side_by_side=args.side_by_side, optimize=not args.no_optimize, device=args.device,
                    precision=args.precision)
    logger.info(f"{len(result.poses)} frames at {result.poses.fps:g} fps; wrote "
                + ", ".join(map(str, result.written)))
