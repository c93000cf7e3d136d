"""`dancesynth train-pose`: train a music-to-pose (stage-1) method on a dance dataset."""

from __future__ import annotations

import argparse

from stage1_pose.registry import method_names

NAME = "train-pose"
HELP = "train a music-to-pose model (dance_revolution, lstm, ren, ...) on a dataset folder"
DESCRIPTION = """\
Train a stage-1 method on DATA (a folder made by `dancesynth make-dataset`) into RUN_DIR:
  RUN_DIR/latest.safetensors + latest.json    the model (weights, config, feature statistics, fps, canvas)
  RUN_DIR/latest.training.pt                  optimizer/RNG/data position for --resume
  RUN_DIR/metrics.csv, loss.png               per-epoch mean of every loss the method logs
  RUN_DIR/previews/epoch_XXXX.mp4             a generated dance for a validation song every --preview-every epochs
                                              (at most one per --preview-gap minutes)

--resume continues a stopped or killed run exactly (same final weights as an uninterrupted run); with a
larger --epochs it extends a finished one. Presets: small (CPU, minutes) and paper (published settings);
--set FIELD=VALUE changes one config field (e.g. --set lstm_hidden=256 --set curriculum=quadratic).
Multi-process: torchrun --nproc_per_node N -m apps.cli train-pose ... (batch size is global).

examples:
  dancesynth train-pose --method dance_revolution --data data/ --out runs/dr
  dancesynth train-pose --method dance_revolution --data data/ --out runs/dr --resume --epochs 200
  dancesynth train-pose --method lstm --data data/ --out runs/lstm --minutes 10
  dancesynth train-pose --method dance_revolution --preset paper --device cuda --data data/ --out runs/dr-paper
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--method", required=True, choices=method_names(), help="the stage-1 method")
    parser.add_argument("--data", required=True, metavar="DIR", help="dataset folder (dancesynth make-dataset)")
    parser.add_argument("--out", required=True, metavar="RUN_DIR", help="run folder for the model and logs")
    parser.add_argument("--preset", default="small", help="config preset: small (CPU) or paper (default small)")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", dest="overrides",
                        help="override one field of the method config (repeatable)")
    parser.add_argument("--epochs", type=int, help="total epochs (default: the preset's)")
    parser.add_argument("--minutes", type=float, help="stop (with a checkpoint) after this many minutes")
    parser.add_argument("--batch-size", type=int, help="global batch size in windows (default: the preset's)")
    parser.add_argument("--window", type=int, metavar="FRAMES", help="training window length in pose frames")
    parser.add_argument("--resume", action="store_true", help="continue the run in RUN_DIR exactly")
    parser.add_argument("--checkpoint-every", type=int, default=200, metavar="STEPS")
    parser.add_argument("--preview-every", type=int, default=10, metavar="EPOCHS", help="0 = no previews")
    parser.add_argument("--preview-gap", type=float, default=2.0, metavar="MINUTES",
                        help="skip a due preview when the last one is less than this long ago (default 2)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=0, help="data loader worker processes")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")


def _overrides(items: list[str]) -> dict[str, str]:
    from dancesynth.core.errors import DancesynthError

    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise DancesynthError(f"--set {item!r} is not FIELD=VALUE; write e.g. --set lstm_hidden=256.")
        out[key.strip()] = value.strip()
    return out


def run(args: argparse.Namespace) -> None:
    from stage1_pose.train import TrainerConfig, train

    options = TrainerConfig(batch_size=args.batch_size, window_frames=args.window,
                            checkpoint_every=args.checkpoint_every, preview_every=args.preview_every,
                            preview_gap_minutes=args.preview_gap, seed=args.seed, num_workers=args.workers)
    meta = train(args.method, args.data, args.out, preset=args.preset, epochs=args.epochs, resume=args.resume,
                 device=args.device, overrides=_overrides(args.overrides), minutes=args.minutes, options=options)
    print(f"saved {args.out}/latest.safetensors: {meta['method']}, epoch {meta['epoch']}/{meta['epochs']}, "
          f"step {meta['step']}")
