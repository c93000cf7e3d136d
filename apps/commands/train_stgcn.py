"""`dancesynth train-stgcn`: train the ST-GCN whose features Ren et al.'s pose perceptual loss compares."""

from __future__ import annotations

import argparse
from pathlib import Path

from stage1_pose.models.ren.stgcn import STGCN_PRESETS
from stage1_pose.models.ren.perceptual import train_stgcn

NAME = "train-stgcn"
HELP = "train the ST-GCN style classifier used by the ren method's pose perceptual loss"
DESCRIPTION = """\
Train an ST-GCN (spatial-temporal graph convolutional network over the BODY_25 skeleton) to recognise the
dance style of pose windows from a dataset made by `dancesynth make-dataset`. Ren et al. compare generated
and real dances in the feature space of such a network (their pose perceptual loss); the authors' network
was trained on another dataset and is not available, so train one here first.

The run folder receives the weights (safetensors) and a JSON sidecar (kind "stgcn", config, style names,
train and validation accuracy). Pass it to the ren method's full presets (`small`, `paper`) as described
in the README's ren section.

presets: small (4 narrow blocks, CPU, minutes) | paper (10 blocks as in ST-GCN, lr 0.002 as Ren et al.)

examples:
  dancesynth train-stgcn --data data/synth --out runs/stgcn
  dancesynth train-stgcn --data data/synth --out runs/stgcn-paper --preset paper --epochs 30 --device cuda
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", type=Path, required=True, help="dataset folder written by make-dataset")
    parser.add_argument("--out", type=Path, required=True, help="run folder to create (or overwrite)")
    parser.add_argument("--preset", choices=sorted(STGCN_PRESETS), default="small",
                        help="network size and training settings (default %(default)s)")
    parser.add_argument("--epochs", type=int, help="override the preset's number of epochs")
    parser.add_argument("--device", default="auto", help="auto | cpu | cuda (default %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default %(default)s)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> None:
    result = train_stgcn(args.data, args.out, preset=args.preset, epochs=args.epochs, device=args.device,
                         seed=args.seed, progress=not args.quiet)
    print(f"ST-GCN trained for {result['epochs']} epochs: train accuracy {result['train_accuracy']:.1%}, "
          f"validation accuracy {result['val_accuracy']:.1%}; saved to {args.out}")
