"""`dancesynth generate`: a dance (pose sequence) for a song, from a trained stage-1 run."""

from __future__ import annotations

import argparse
import logging

from apps.requests import GenerateRequest

NAME = GenerateRequest.COMMAND
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


add_arguments = GenerateRequest.add_arguments


def run(args: argparse.Namespace) -> None:
    from dancesynth.api import generate

    seq = generate(**GenerateRequest.from_namespace(args).api_kwargs())
    logger.info(f"wrote {args.out}: {len(seq)} frames at {seq.fps:g} fps ({seq.duration:.1f} s), "
                f"{seq.width}x{seq.height} canvas" + (f"; preview {args.preview}" if args.preview else ""))
