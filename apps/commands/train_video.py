"""`dancesynth train-video`: learn to render the person of one video in any pose."""

from __future__ import annotations

import argparse

from dancesynth.core.errors import DancesynthError
from stage2_video.models.pix2pixhd import PRESETS

NAME = "train-video"
HELP = "train the appearance model (pix2pixHD + temporal smoothing) on a video of the target person"
DESCRIPTION = """\
Train a pix2pixHD appearance model with Everybody Dance Now's temporal smoothing on ONE video of the
target person. Poses are extracted from the video with the bundled BlazePose and cached in RUN_DIR/poses.npz
(or given with --poses, e.g. the ground-truth poses of a synthetic target video). The last 15 % of the video
is held out: RUN_DIR/validation.csv reports SSIM / PSNR on it at every checkpoint, RUN_DIR/samples/ has PNG
grids (real | skeleton | generated), RUN_DIR/losses.csv and losses.png the losses.

Stops cleanly after --minutes (checkpointing) or --epochs; --resume continues exactly where it stopped.
Without --vgg-weights the VGG19 perceptual loss is off (a notice says so); nothing is downloaded.
Multi-process: torchrun --nproc_per_node N -m apps.cli train-video ...

examples:
  dancesynth train-video person.mp4 --out runs/person --minutes 20
  dancesynth train-video synthetic.mp4 --poses synthetic_poses.npz --out runs/synth --minutes 20
  dancesynth train-video person.mp4 --out runs/person --resume --minutes 10
  dancesynth train-video person.mp4 --out runs/hd --preset paper --device cuda --vgg-weights vgg19.pth --epochs 200
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("video", metavar="TARGET_VIDEO", help="video of the target person (any FFmpeg format)")
    parser.add_argument("--out", required=True, metavar="RUN_DIR", help="run folder for checkpoints and logs")
    parser.add_argument("--preset", choices=sorted(PRESETS), default="small",
                        help="small: CPU, 128 px, global generator; paper: 1024x512, local enhancer, GPU")
    parser.add_argument("--size", metavar="WxH", help="model resolution override, e.g. 256x256 (multiple of 8)")
    parser.add_argument("--minutes", type=float, help="wall-clock budget of this invocation, in minutes")
    parser.add_argument("--epochs", type=int, help="total epochs (default: the preset's 100 + 100 decaying)")
    parser.add_argument("--batch-size", type=int, help="consecutive-frame pairs per step (preset default)")
    parser.add_argument("--resume", action="store_true", help="continue the run in RUN_DIR exactly")
    parser.add_argument("--poses", metavar="POSES.npz", help="poses of TARGET_VIDEO to use instead of extracting")
    parser.add_argument("--vgg-weights", metavar="FILE", help="local torchvision vgg19 weights (.pth/.safetensors)")
    parser.add_argument("--checkpoint-every", type=int, default=200, metavar="STEPS")
    parser.add_argument("--sample-every", type=int, default=200, metavar="STEPS")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")
    parser.add_argument("--threads", type=int, metavar="N",
                        help="CPU threads for torch (default: torch's choice; 1 is faster on a busy machine)")


def _size(text: str) -> dict:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as e:
        raise DancesynthError(f"--size {text!r} is not WIDTHxHEIGHT; write e.g. 256x256.") from e
    return {"width": w, "height": h}


def run(args: argparse.Namespace) -> None:
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    from stage2_video.train import TrainOptions, train_video

    overrides = _size(args.size) if args.size else {}
    if args.batch_size:
        overrides["batch_size"] = args.batch_size
    options = TrainOptions(minutes=args.minutes, epochs=args.epochs, checkpoint_every=args.checkpoint_every,
                           sample_every=args.sample_every, seed=args.seed)
    meta = train_video(args.video, args.out, args.preset, options, resume=args.resume, poses=args.poses,
                       vgg_weights=args.vgg_weights, device=args.device, overrides=overrides)
    val = meta.get("validation", {})
    print(f"saved {args.out}/latest.safetensors: epoch {meta['epoch']}, step {meta['step']}, "
          f"held-out SSIM {val.get('ssim', float('nan')):.3f}, PSNR {val.get('psnr', float('nan')):.2f} dB")
