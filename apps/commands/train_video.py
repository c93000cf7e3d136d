"""`dancesynth train-video`: learn to render the person of one video in any pose."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import (
    add_precision_argument,
    add_trainer_arguments,
    existing_file,
    non_negative_int,
    output_folder,
    positive_int,
)
from apps.config_flags import add_config_arguments, chosen_fields, print_config, resolve_config
from dancesynth.core.errors import DancesynthError
from stage2_video.presets import describe_presets, preset_names

NAME = "train-video"
HELP = "train the appearance model (pix2pixHD + temporal smoothing) on a video of the target person"
DESCRIPTION = """\
Train a pix2pixHD appearance model with Everybody Dance Now's temporal smoothing on ONE video of the
target person. Poses are extracted from the video with the bundled BlazePose and cached in RUN_DIR/poses.npz
(or given with --poses, e.g. the ground-truth poses of a synthetic target video). The last 15 % of the video
is held out: RUN_DIR/validation.csv reports SSIM / PSNR on it at every checkpoint, RUN_DIR/samples/ has PNG
grids (real | skeleton | generated), RUN_DIR/losses.csv and losses.png the losses.

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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("video", type=existing_file, metavar="TARGET_VIDEO",
                        help="video of the target person (any FFmpeg format)")
    parser.add_argument("--out", type=output_folder, required=True, metavar="RUN_DIR",
                        help="run folder for checkpoints and logs")
    parser.add_argument("--preset", choices=preset_names(), default="small",
                        help=f"the model's preset (default small); {describe_presets()}")
    parser.add_argument("--size", metavar="WxH", help="model resolution override, e.g. 256x256 (multiple of 8)")
    parser.add_argument("--epochs", type=positive_int, help="total epochs (default: the preset's 100 + 100 decaying)")
    add_trainer_arguments(parser, "--epochs")
    parser.add_argument("--batch-size", type=positive_int, help="consecutive-frame pairs per step (preset default)")
    parser.add_argument("--poses", type=existing_file, metavar="POSES.npz",
                        help="poses of TARGET_VIDEO to use instead of extracting")
    parser.add_argument("--vgg-weights", type=existing_file, metavar="FILE",
                        help="local torchvision vgg19 weights (.pth/.safetensors)")
    parser.add_argument("--checkpoint-every", type=positive_int, default=200, metavar="STEPS")
    parser.add_argument("--sample-every", type=positive_int, default=200, metavar="STEPS")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")
    add_precision_argument(parser, "the forward passes (weights stay float32)")
    parser.add_argument("--threads", type=positive_int, metavar="N",
                        help="CPU threads for torch (default: torch's choice; 1 is faster on a busy machine)")
    add_config_arguments(parser, "lambda_l1=5")


def _size(text: str) -> dict:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as e:
        raise DancesynthError(f"--size {text!r} is not WIDTHxHEIGHT; write e.g. 256x256.") from e
    return {"width": w, "height": h}


def run(args: argparse.Namespace) -> None:
    from stage2_video.models.pix2pixhd import PRESETS

    flags = _size(args.size) if args.size else {}
    if args.batch_size:
        flags["batch_size"] = args.batch_size
    config = resolve_config(PRESETS[args.preset], args, flags)
    if args.print_config:
        print_config(config, args.print_config)
        return
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    from dancesynth.api import train_video

    chosen = chosen_fields(PRESETS[args.preset], config, args, flags)
    meta = train_video(args.video, out=args.out, preset=args.preset, overrides=chosen,
                       minutes=args.minutes, epochs=args.epochs, resume=args.resume, poses=args.poses,
                       vgg_weights=args.vgg_weights, checkpoint_every=args.checkpoint_every,
                       sample_every=args.sample_every, seed=args.seed, device=args.device,
                       precision=args.precision)
    val = meta.get("validation", {})
    logger.info(f"saved {args.out}: epoch {meta['epoch']}, step {meta['step']}, "
                f"held-out SSIM {val.get('ssim', float('nan')):.3f}, PSNR {val.get('psnr', float('nan')):.2f} dB")
