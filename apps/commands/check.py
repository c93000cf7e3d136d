"""`dancesynth check`: the quality check of a trained stage-1 run on held-out songs."""

from __future__ import annotations

import argparse
import json
import logging

from apps.arguments import non_negative_int, output_file, positive_float, positive_int

NAME = "check"
HELP = "check a trained pose model on held-out songs: no freezing, seeds differ, movement on the beat"
DESCRIPTION = """\
Generate a dance with every --seeds seed for the first --clips held-out (test, then val) songs of the run's
dataset (or --data), --seconds of each, from the dataset's music features and beats, and judge each dance:
  no freeze     mean joint speed over the last 10 s >= 50 % of the first 10 s and >= 50 % of the real
                held-out dances' mean speed;
  seeds differ  distance to the nearest other seed's dance >= 10 % of the distance between two real dances
                of one style (also split into body relative to the hip, and root: where the dancer stands);
  beats         beat hit rate (kinematic beats within 2 frames of a music beat) above chance by 0.10, chance
                being the hit rate of the same kinematic beats shifted by random offsets.
Prints a table of measures per dance (real dance included), the mean joint speed by beat phase (tenths of the
interval from one music beat to the next; real dances slow down on the beat) and PASS/FAIL per criterion.
Exits 0 whether the criteria pass or not.

examples:
  dancesynth check runs/dr
  dancesynth check runs/dr --clips 4 --seconds 60 --seeds 0 1 --json runs/dr/check.json
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # Defaults live in stage1_pose.quality_check.CheckOptions; None here means "use it" (keeps --help fast).
    parser.add_argument("run", metavar="RUN", help="stage-1 run folder written by train-pose")
    parser.add_argument("--data", metavar="DATASET", help="dataset folder (default: the one the run was trained on)")
    parser.add_argument("--clips", type=positive_int, help="held-out songs to check (default 3)")
    parser.add_argument("--seconds", type=positive_float, help="seconds of each song to dance to (default 60)")
    parser.add_argument("--seeds", type=non_negative_int, nargs="+", help="seeds, at least two (default 0 1)")
    parser.add_argument("--json", type=output_file, metavar="OUT.json",
                        help="also write every measure and verdict as JSON")
    parser.add_argument("--precision", choices=("auto", "fp32", "int8"),
                        help="decoder weights: int8 is ~3x faster on CPU; auto = int8 on CPU, fp32 on GPU")
    parser.add_argument("--device", help="auto, cpu or cuda (default auto)")


def run(args: argparse.Namespace) -> None:
    from dancesynth.core.fileio import atomic_path, check_outputs
    from stage1_pose.quality_check import CheckOptions, check_run, report_text

    check_outputs({"JSON report": args.json}, {"pose model": args.run, "dataset": args.data})
    given = {k: getattr(args, k) for k in ("clips", "seconds", "device", "precision") if getattr(args, k) is not None}
    if args.seeds is not None:
        given["seeds"] = tuple(args.seeds)
    result = check_run(args.run, args.data, CheckOptions(**given))
    logger.info(report_text(result))
    if args.json:
        with atomic_path(args.json) as tmp:
            tmp.write_text(json.dumps(result.to_json(), indent=1))
        logger.info(f"wrote {args.json}")
