"""`dancesynth train-style-classifier`: the pose style classifier behind FID and ACC."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import non_negative_int, output_folder, positive_int
from apps.requests import add_trainer_arguments

NAME = "train-style-classifier"
HELP = "train the dance style classifier used by `dancesynth evaluate` (FID features, ACC)"
DESCRIPTION = """\
Train an LSTM (hidden 200, as in Dance Revolution) to tell the dataset's styles apart from 4-s windows of the
train split's dances (normalised BODY_25 coordinates and velocities). Its time-averaged hidden state is the
feature in which FID, diversity, multimodality and the cross-modal distance are measured; its predictions give
ACC. Saved as a run folder (kind "style_classifier": latest.json and its checkpoint, metrics.csv, loss.png),
with a checkpoint every 50 steps and on Ctrl-C or SIGTERM that --resume continues exactly (--minutes bounds
the run's training time in all); prints the accuracy on the test split's real dances, which should be close
to 100 %% for the metrics to mean anything.

examples:
  dancesynth train-style-classifier --data data/builtin --out runs/style_classifier
  dancesynth train-style-classifier --data data/builtin --out runs/clf_small --preset small --steps 50
  dancesynth train-style-classifier --data data/builtin --out runs/clf_small --resume --steps 200
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", required=True, metavar="DIR", help="dataset folder (dancesynth make-dataset)")
    parser.add_argument("--out", type=output_folder, required=True, metavar="RUN_DIR",
                        help="run folder to write (or continue with --resume)")
    parser.add_argument("--preset", choices=("paper", "small"), default="paper", help="network size and schedule")
    parser.add_argument("--steps", type=positive_int, help="total optimiser steps (default: the preset's or the run's)")
    add_trainer_arguments(parser, "--steps")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="random seed")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")


def run(args: argparse.Namespace) -> None:
    from dancesynth.core.fileio import check_outputs
    from stage1_pose.style_classifier import train_on_dataset

    check_outputs({}, {"dataset": args.data}, folders={"run folder": args.out})
    clf, test_acc = train_on_dataset(args.data, args.out, preset=args.preset, steps=args.steps, minutes=args.minutes,
                                     seed=args.seed, device=args.device, resume=args.resume)
    logger.info(f"wrote {args.out}: styles {', '.join(clf.styles)}; accuracy on the test split's real dances "
                f"{100 * test_acc:.1f} %")
