"""`dancesynth demo`: the whole pipeline on built-in data, from nothing to a dancing video."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import non_negative_int, output_folder, positive_float

NAME = "demo"
HELP = "build the built-in dataset, train small models and make a dancing video (about 15 min on 2 CPU cores)"
DESCRIPTION = """\
Run the whole pipeline on data the project makes itself, within a time budget:
  1. the built-in dataset of synthesised songs and dances (3 styles),
  2. a small Dancing2Music pose model (the paper's ablation without the composition phase, which needs
     far longer than the demo's minutes), whose units are warped onto the song's beats,
  3. a synthetic target person's video and a small pix2pixHD appearance model of them,
  4. a dancing video for the held-out song whose real dance moves most, a skeleton video and a side-by-side
     video,
  5. OUT/summary.md with beat metrics of the generated dance vs the real one, held-out SSIM/PSNR of the
     appearance model, a strip of frames and the time each step took.
Each step is skipped when its output exists, so an interrupted demo continues where it stopped.

example:
  dancesynth demo --out demo_output --minutes 15
"""

logger = logging.getLogger(__name__)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=output_folder, default="demo_output", metavar="DIR",
                   help="output folder (default demo_output)")
    p.add_argument("--minutes", type=positive_float, default=15.0, help="total time budget in minutes (default 15)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="random seed (default 0)")
    p.add_argument("--device", default="auto", help="auto (GPU when available), cpu or cuda (default auto)")


def run(args: argparse.Namespace) -> None:
    from apps.demo import run_demo

    written = run_demo(args.out, minutes=args.minutes, seed=args.seed, device=args.device)
    logger.info("wrote " + ", ".join(map(str, written)))
