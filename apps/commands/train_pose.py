"""`dancesynth train-pose`: train a music-to-pose (stage-1) method on a dance dataset."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import add_trainer_arguments, non_negative_float, non_negative_int, output_folder, positive_int
from apps.config_flags import add_config_arguments, print_config, resolve_config
from dancesynth.core.config import config_to_dict

NAME = "train-pose"
HELP = "train a music-to-pose model (dance_revolution, lstm, ren, ...) on a dataset folder"
DESCRIPTION = """\
Train a stage-1 method on DATA (a folder made by `dancesynth make-dataset`) into RUN_DIR:
  RUN_DIR/latest.json + ckpt-<step>-<id>/     the model (weights, config, feature statistics, fps, canvas) and
                                              optimizer/RNG/data position for --resume; kill -9 safe
  RUN_DIR/metrics.csv, loss.png               per-epoch mean of every loss the method logs
  RUN_DIR/previews/epoch_XXXX.mp4             a generated dance for a validation song every --preview-every epochs
                                              (at most one per --preview-gap minutes)

Ctrl-C or SIGTERM saves a checkpoint first; --resume continues a stopped or killed run exactly (same final
weights as an uninterrupted run); --epochs and --minutes are the run's totals, so larger ones extend a finished
run. The method config is the --preset (small: CPU, minutes; paper:
published settings), then the settings of a --config TOML file, then --batch-size / --window, then each
--set FIELD=VALUE (e.g. --set lstm_hidden=256 --set curriculum=quadratic); --print-config shows the result
and exits without training.
Multi-process: torchrun --nproc_per_node N -m apps.cli train-pose ... (batch size is global).

examples:
  dancesynth train-pose --method dance_revolution --data data/ --out runs/dr
  dancesynth train-pose --method dance_revolution --data data/ --out runs/dr --resume --epochs 200
  dancesynth train-pose --method lstm --data data/ --out runs/lstm --minutes 10
  dancesynth train-pose --method dance_revolution --preset paper --device cuda --data data/ --out runs/dr-paper
  dancesynth train-pose --method lstm --data data/ --out runs/lstm --set hidden=256 --print-config > lstm.toml
  dancesynth train-pose --method lstm --data data/ --out runs/lstm --config lstm.toml
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from stage1_pose.registry import method_names

    parser.add_argument("--method", required=True, choices=method_names(), help="the stage-1 method")
    parser.add_argument("--data", required=True, metavar="DIR", help="dataset folder (dancesynth make-dataset)")
    parser.add_argument("--out", type=output_folder, required=True, metavar="RUN_DIR",
                        help="run folder for the model and logs")
    parser.add_argument("--preset", default="small", help="config preset: small (CPU) or paper (default small)")
    add_config_arguments(parser, "hidden=256")
    parser.add_argument("--epochs", type=positive_int, help="total epochs (default: the preset's)")
    add_trainer_arguments(parser, "--epochs")
    parser.add_argument("--batch-size", type=positive_int, help="global batch size in windows (default: the preset's)")
    parser.add_argument("--window", type=positive_int, metavar="FRAMES", help="training window length in pose frames")
    parser.add_argument("--checkpoint-every", type=positive_int, default=200, metavar="STEPS")
    parser.add_argument("--preview-every", type=non_negative_int, default=10, metavar="EPOCHS", help="0 = no previews")
    parser.add_argument("--preview-gap", type=non_negative_float, default=2.0, metavar="MINUTES",
                        help="skip a due preview when the last one is less than this long ago (default 2)")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument("--workers", type=non_negative_int, default=0, help="data loader worker processes")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")


def run(args: argparse.Namespace) -> None:
    from stage1_pose.registry import make_config

    flags = {"batch_size": args.batch_size, "window_frames": args.window}
    config = resolve_config(make_config(args.method, args.preset), args,
                            {key: value for key, value in flags.items() if value is not None})
    if args.print_config:
        print_config(config, args.print_config)
        return
    from dancesynth.api import train_pose

    meta = train_pose(args.method, data=args.data, out=args.out, preset=args.preset, overrides=config_to_dict(config),
                      epochs=args.epochs, minutes=args.minutes, batch_size=args.batch_size, window=args.window,
                      resume=args.resume, checkpoint_every=args.checkpoint_every, preview_every=args.preview_every,
                      preview_gap=args.preview_gap, seed=args.seed, workers=args.workers, device=args.device)
    logger.info(f"saved {args.out}: {meta['method']}, epoch {meta['epoch']}/{meta['epochs']}, "
                f"step {meta['step']}")
