"""`dancesynth train-stgcn`: train the ST-GCN whose features Ren et al.'s pose perceptual loss compares."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from apps.arguments import non_negative_int, output_folder, positive_int
from apps.requests import add_trainer_arguments

NAME = "train-stgcn"
HELP = "train the ST-GCN style classifier used by the ren method's pose perceptual loss"
DESCRIPTION = """\
Train an ST-GCN (spatial-temporal graph convolutional network over the BODY_25 skeleton) to recognise the
dance style of pose windows from a dataset made by `dancesynth make-dataset`. Ren et al. compare generated
and real dances in the feature space of such a network (their pose perceptual loss); the authors' network
was trained on another dataset and is not available, so train one here first.

The run folder receives a checkpoint after every epoch (weights as safetensors, a JSON sidecar latest.json
with kind "stgcn", config, style names and, at the end, train and validation accuracy), metrics.csv and
loss.png. Ctrl-C or SIGTERM saves a checkpoint first, --resume continues a stopped training exactly, and
--minutes bounds the run's training time in all. Pass the folder to the ren method's full presets
(`small`, `paper`) as described in docs/methods/ren.md.

presets: small (4 narrow blocks, CPU, minutes) | paper (10 blocks as in ST-GCN, lr 0.002 as Ren et al.)

examples:
  dancesynth train-stgcn --data data/synth --out runs/stgcn
  dancesynth train-stgcn --data data/synth --out runs/stgcn-paper --preset paper --epochs 30 --device cuda
  dancesynth train-stgcn --data data/synth --out runs/stgcn-paper --resume --epochs 40
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", type=Path, required=True, help="dataset folder written by make-dataset")
    parser.add_argument("--out", type=output_folder, required=True, metavar="RUN_DIR",
                        help="run folder to create (or continue with --resume)")
    parser.add_argument("--preset", choices=("paper", "small"), default="small",
                        help="network size and training settings (default %(default)s)")
    parser.add_argument("--epochs", type=positive_int, help="total epochs (default: the preset's or the run's)")
    add_trainer_arguments(parser, "--epochs")
    parser.add_argument("--device", default="auto", help="auto | cpu | cuda (default %(default)s)")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="random seed (default %(default)s)")


def run(args: argparse.Namespace) -> None:
    from dancesynth.core.fileio import check_outputs
    from stage1_pose.models.ren.perceptual import train_stgcn

    check_outputs({}, {"dataset": args.data}, folders={"run folder": args.out})
    result = train_stgcn(args.data, args.out, preset=args.preset, epochs=args.epochs, device=args.device,
                         seed=args.seed, resume=args.resume, minutes=args.minutes)
    logger.info(f"ST-GCN trained for {result['epochs']} epochs: train accuracy {result['train_accuracy']:.1%}, "
                f"validation accuracy {result['val_accuracy']:.1%}; saved to {args.out}")
