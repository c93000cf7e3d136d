"""`dancesynth train-style-classifier`: the pose style classifier behind FID and ACC."""

from __future__ import annotations

import argparse

NAME = "train-style-classifier"
HELP = "train the dance style classifier used by `dancesynth evaluate` (FID features, ACC)"
DESCRIPTION = """\
Train an LSTM (hidden 200, as in Dance Revolution) to tell the dataset's styles apart from 4-s windows of the
train split's dances (normalised BODY_25 coordinates and velocities). Its time-averaged hidden state is the
feature in which FID, diversity, multimodality and the cross-modal distance are measured; its predictions give
ACC. Saved as a run folder (latest.safetensors + latest.json, kind "style_classifier"); prints the accuracy on
the test split's real dances, which should be close to 100 %% for the metrics to mean anything.

examples:
  dancesynth train-style-classifier --data data/builtin --out runs/style_classifier
  dancesynth train-style-classifier --data data/builtin --out runs/clf_small --preset small --steps 50
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", required=True, metavar="DIR", help="dataset folder (dancesynth make-dataset)")
    parser.add_argument("--out", required=True, metavar="RUN_DIR", help="run folder to write")
    parser.add_argument("--preset", choices=("paper", "small"), default="paper", help="network size and schedule")
    parser.add_argument("--steps", type=int, help="optimiser steps (default: the preset's)")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")


def run(args: argparse.Namespace) -> None:
    import dataclasses

    from dancesynth.core.device import resolve_device
    from dancesynth.core.errors import DancesynthError
    from stage1_pose.style_classifier import PRESETS, save_style_classifier, train_on_dataset

    config = PRESETS[args.preset]
    if args.steps is not None:
        if args.steps < 1:
            raise DancesynthError("--steps must be at least 1.")
        config = dataclasses.replace(config, steps=args.steps)
    clf, test_acc = train_on_dataset(args.data, config, resolve_device(args.device), seed=args.seed)
    save_style_classifier(args.out, clf, {"test_accuracy": test_acc, "data": str(args.data)})
    print(f"wrote {args.out}: styles {', '.join(clf.styles)}; accuracy on the test split's real dances "
          f"{100 * test_acc:.1f} %")
