"""`dancesynth train-pose`: train a music-to-pose (stage-1) method on a dance dataset."""

from __future__ import annotations

import argparse
import logging

from apps.config_flags import print_config, resolve_config
from apps.requests import TrainPoseRequest
from dancesynth.core.config import config_to_dict

NAME = TrainPoseRequest.COMMAND
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


add_arguments = TrainPoseRequest.add_arguments


def run(args: argparse.Namespace) -> None:
    from stage1_pose.registry import make_config

    request = TrainPoseRequest.from_namespace(args)
    flags = {"batch_size": request.batch_size, "window_frames": request.window}
    config = resolve_config(make_config(request.method, request.preset), request,
                            {key: value for key, value in flags.items() if value is not None})
    if request.print_config:
        print_config(config, request.print_config)
        return
    from dancesynth.api import train_pose

    meta = train_pose(**request.api_kwargs(), overrides=config_to_dict(config))
    logger.info(f"saved {args.out}: {meta['method']}, epoch {meta['epoch']}/{meta['epochs']}, "
                f"step {meta['step']}")
