"""`dancesynth demo`: the whole pipeline on built-in data, from nothing to a dancing video."""

from __future__ import annotations

import argparse
import logging

from apps.requests import DemoRequest

NAME = DemoRequest.COMMAND
HELP = "train an appearance model of a synthetic person and make them dance to a built-in song (about 15 min)"
DESCRIPTION = """\
Run the main job on data the project makes itself, within a time budget:
  1. a few built-in synthesised songs, none of which the shipped pose model has heard,
  2. a synthetic target person's video (512 px high) and an appearance model of them, trained for every
     minute of the budget but the dance step's (256 px on GPUs and bf16 CPUs, 128 px elsewhere),
  3. the shipped pose model (Dance Revolution) dances one song; the dance is rendered in the target's
     scene at the target video's resolution: a dancing video, a skeleton video and a side-by-side video,
  4. OUT/summary.md with beat metrics of the generated dance vs the song's real one, held-out SSIM/PSNR of
     the appearance model, a strip of frames and the time each step took.
Each step is skipped when its output exists, so an interrupted demo continues where it stopped.

example:
  dancesynth demo --out demo_output --minutes 15
"""

logger = logging.getLogger(__name__)


add_arguments = DemoRequest.add_arguments


def run(args: argparse.Namespace) -> None:
    from apps.demo import run_demo

    written = run_demo(**DemoRequest.from_namespace(args).api_kwargs())
    logger.info("wrote " + ", ".join(map(str, written)))
