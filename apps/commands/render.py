"""`dancesynth render`: pose sequence -> video of the target person."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import add_precision_argument, existing_file, output_file, positive_int

NAME = "render"
HELP = "render a pose sequence as a video of the person a train-video model learned"
DESCRIPTION = """\
Render POSES (a dancesynth .npz pose file, e.g. from `dancesynth generate` or `dancesynth extract-poses`) with
an appearance model trained by `dancesynth train-video`. The poses are first normalised onto the target
video (Everybody Dance Now: scale and position from ankle heights and body size; --no-normalize skips it,
for poses already on the target's canvas). Frames are streamed to the H.264 encoder at the poses' fps, at the
model's resolution; --audio muxes a song (trimmed to the video length).

examples:
  dancesynth render dance.npz --model runs/person --out dance.mp4 --audio song.mp3
  dancesynth render runs/person/poses.npz --model runs/person --out replay.mp4 --no-normalize
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("poses", type=existing_file, metavar="POSES", help="pose file (.npz, BODY_25)")
    parser.add_argument("--model", required=True, metavar="RUN_DIR", help="run folder written by train-video")
    parser.add_argument("--out", type=output_file, required=True, metavar="VIDEO.mp4", help="output video")
    parser.add_argument("--audio", type=existing_file, metavar="SONG", help="audio file to mux (any FFmpeg format)")
    parser.add_argument("--no-normalize", action="store_true", help="use the poses as they are (target canvas)")
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
    from dancesynth.core.media import probe_video

    path = render(args.poses, model=args.model, out=args.out, audio=args.audio, normalize=not args.no_normalize,
                  optimize=not args.no_optimize, device=args.device, precision=args.precision)
    video = probe_video(path)
    logger.info(f"wrote {path}: {video.num_frames} frames at {video.fps:g} fps, {video.width}x{video.height}")
