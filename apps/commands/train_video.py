"""`dancesynth train-video`: learn to render the person of one video in any pose."""

from __future__ import annotations

import argparse
import logging

from apps.config_flags import chosen_fields, print_config, resolve_config
from apps.requests import TrainVideoRequest
from dancesynth.core.errors import DancesynthError

NAME = TrainVideoRequest.COMMAND
HELP = "train the appearance model (pix2pixHD + temporal smoothing) on a video of the target person"
DESCRIPTION = """\
Train a pix2pixHD appearance model with Everybody Dance Now's temporal smoothing on ONE video of the
target person. Poses are extracted from the video with the bundled BlazePose and cached in RUN_DIR/poses.npz
(or given with --poses, e.g. the ground-truth poses of a synthetic target video). The last 15 % of the video
is held out: RUN_DIR/validation.csv reports SSIM / PSNR on it at every checkpoint, RUN_DIR/samples/ has PNG
grids (real | skeleton | generated), RUN_DIR/losses.csv and losses.png the losses. With the warped prior (small,
medium) the 10 % before it is not learnt from either: it scores every checkpoint (select_ssim), the prior alone
included, and the model renders with the best, so training that makes the person worse is not used; these models
are scored as they render, at the output's size, inside the person's box.

Stops with a checkpoint when the run has trained --minutes in all (every call together) or --epochs, and on
Ctrl-C or SIGTERM; --resume continues exactly where it stopped.
The model config is the --preset, then the settings of a --config TOML file, then --size / --batch-size, then
each --set FIELD=VALUE (e.g. --set lambda_l1=5); --print-config shows the result and exits without training.
Without --vgg-weights the VGG19 perceptual loss is off (a notice says so); nothing is downloaded.
Multi-process: torchrun --nproc_per_node N -m apps.cli train-video ...

examples:
  dancesynth train-video person.mp4 --out runs/person --minutes 20
  dancesynth train-video synthetic.mp4 --poses synthetic_poses.npz --out runs/synth --minutes 20
  dancesynth train-video person.mp4 --out runs/person --resume --minutes 30   # 10 more minutes
  dancesynth train-video person.mp4 --out runs/hd --preset paper --device cuda --vgg-weights vgg19.pth --epochs 200
  dancesynth train-video person.mp4 --out runs/p --set ngf=64 --set n_blocks=6 --print-config > model.toml
  dancesynth train-video person.mp4 --out runs/p --config model.toml --minutes 20
"""

logger = logging.getLogger(__name__)


add_arguments = TrainVideoRequest.add_arguments


def _size(text: str) -> dict:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as e:
        raise DancesynthError(f"--size {text!r} is not WIDTHxHEIGHT; write e.g. 256x256.") from e
    return {"width": w, "height": h}


def run(args: argparse.Namespace) -> None:
    from stage2_video.models.pix2pixhd import PRESETS

    request = TrainVideoRequest.from_namespace(args)
    flags = _size(request.size) if request.size else {}
    if request.batch_size:
        flags["batch_size"] = request.batch_size
    preset_config = PRESETS[request.preset]
    config = resolve_config(preset_config, request, flags)
    if request.print_config:
        print_config(config, request.print_config)
        return
    import torch

    if request.threads:
        torch.set_num_threads(request.threads)
    from dancesynth.api import train_video

    meta = train_video(**request.api_kwargs(), overrides=chosen_fields(preset_config, config, request, flags))
    val = meta.get("validation", {})
    kept = f", renders with step {meta['best']['step']} (best on the selection frames)" if meta.get("best") else ""
    logger.info(f"saved {args.out}: epoch {meta['epoch']}, step {meta['step']}, "
                f"held-out SSIM {val.get('ssim', float('nan')):.3f}, PSNR {val.get('psnr', float('nan')):.2f} dB"
                f"{kept}")
