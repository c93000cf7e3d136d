"""Held-out quality of a trained appearance model (a `dancesynth train-video` run folder).

Renders the held-out part of the target video (the last ``val_fraction``, never trained on) from its poses,
frame after frame as `dancesynth render` does, and prints:
  * SSIM and PSNR (dB) of generated vs real frames (model resolution), over the frames whose pose has a torso
    (the ones the trainer learns from and validates on);
  * PCK@0.1 (torso size) between the pose BlazePose re-extracts from the generated frames and the commanded
    pose (the run's poses.npz, i.e. what the model was asked to draw); the same extraction on the real frames
    is printed as the ceiling the extractor allows. Frames go to BlazePose as decoded arrays (no re-encoding).
  * with ``--ground-truth POSES.npz`` (the true joints of a synthetic target video), PCK of the generated and
    the real frames against those joints too. Small toes are not scored there: BlazePose has no such point.

    python benchmarks/eval_video.py runs/synth --frames 120 --save-video held_out.mp4
    python benchmarks/eval_video.py runs/synth --ground-truth synthetic_poses.npz
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from dancesynth.core.checkpoint import load_meta
from dancesynth.core.config import config_from_dict
from dancesynth.core.media import VideoWriter
from dancesynth.core.progress import track
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence
from stage2_video.extract import ExtractConfig, extract_frames
from stage2_video.framing import Framing, usable_frames
from stage2_video.models.pix2pixhd import Pix2PixHDConfig
from stage2_video.quality import pck, psnr, ssim
from stage2_video.render import load_appearance_model, render_frames
from stage2_video.train import KIND
from stage2_video.training_data import POSES_FILE, frames_file, split_ranges


def framed(seq: PoseSequence, framings: list[Framing]) -> PoseSequence:
    """``seq`` in model-image pixels, frame t framed by ``framings[t]``."""
    kp = seq.keypoints.copy()
    for t, framing in enumerate(framings):
        kp[t, :, :2] = framing.points(kp[t, :, :2])
    return PoseSequence(kp, seq.fps, framings[0].out_width, framings[0].out_height)


def extracted(frames: list[np.ndarray], fps: float, start: np.ndarray | None = None) -> PoseSequence:
    """The pose BlazePose finds in ``frames`` (model-image pixels); frames where it finds nobody score as misses.
    ``start``: the commanded first pose, so the tracker follows whoever stands there (else the largest person near
    the centre: in a large scene a false find of its first whole-frame search decided every frame after it)."""
    size = (frames[0].shape[1], frames[0].shape[0])
    found = extract_frames(frames, fps, size, ExtractConfig(max_missing_fraction=1.0), progress=False, start=start)
    # Gap filling gives frames without a detection interpolated joints; here they must count as misses.
    kp = found.poses.keypoints.copy()
    kp[~found.found, :, 2] = 0.0
    return found.poses.replace(kp)


def without_small_toes(seq: PoseSequence) -> PoseSequence:
    """``seq`` with the small toes marked absent (BlazePose never reports them, so they cannot be scored)."""
    kp = seq.keypoints.copy()
    kp[:, [JOINT_INDEX["LSmallToe"], JOINT_INDEX["RSmallToe"]], 2] = 0.0
    return PoseSequence(kp, seq.fps, seq.width, seq.height)


@dataclass
class HeldOut:
    """What :func:`held_out_quality` measured and rendered (model-resolution frames)."""

    frames: range  # scored frame indices of the target video (held out unless training_frames)
    commanded: PoseSequence  # their poses (canvas pixels)
    framings: list[Framing]  # how each was framed
    generated: list[np.ndarray]
    reals: list[np.ndarray]
    ssim: float
    psnr: float
    pck: list[tuple[str, float]]


def held_out_quality(run_dir: Path, frames: int = 0, device: str = "auto", ground_truth: Path | None = None,
                     precision: str = "auto", training_frames: bool = False) -> HeldOut:
    """Render the run's held-out frames (the first ``frames``, 0 = all) in ``precision`` and score them (see the
    module doc). ``training_frames``: score as many of the last training frames instead (learnt vs generalised)."""
    meta = load_meta(run_dir, KIND)
    config = config_from_dict(Pix2PixHDConfig, meta["config"])
    model = load_appearance_model(run_dir, device, precision=precision)
    poses = PoseSequence.load(run_dir / POSES_FILE)
    real = np.load(run_dir / frames_file(model.framing), mmap_mode="r")
    train, held_out = split_ranges(len(poses), config.val_fraction)
    if training_frames:
        held_out = range(max(train.start, train.stop - len(held_out)), train.stop)
    stop = min(held_out.start + frames, held_out.stop) if frames else held_out.stop
    commanded = poses.slice_frames(held_out.start, stop)
    # Framed as in training: the following box's path is smoothed over the whole video, not the slice.
    framings = model.framing.frames(poses)[held_out.start:stop]
    generated = list(track(render_frames(model, commanded, framings=framings),
                           total=len(commanded), desc="render"))
    reals = [np.asarray(real[t]) for t in range(held_out.start, stop)]
    target = framed(commanded, framings)
    start = target.keypoints[0]
    from_generated, from_real = extracted(generated, poses.fps, start), extracted(reals, poses.fps, start)
    rows = [("generated vs commanded", pck(from_generated, target)),
            ("real frames vs commanded (ceiling)", pck(from_real, target))]
    if ground_truth:
        truth = PoseSequence.load(ground_truth).slice_frames(held_out.start, stop)
        truth = without_small_toes(framed(truth, framings))
        rows += [("generated vs true joints", pck(from_generated, truth)),
                 ("real frames vs true joints", pck(from_real, truth))]
    # Scored where the trainer validates: frames whose pose has a plausible torso.
    scored = [(g, r) for g, r, ok in zip(generated, reals, usable_frames(poses)[held_out.start:stop]) if ok]
    return HeldOut(range(held_out.start, stop), commanded, framings, generated, reals,
                   float(np.mean([ssim(g, r) for g, r in scored])), float(np.mean([psnr(g, r) for g, r in scored])),
                   rows)


def print_quality(run_dir: Path, result: HeldOut) -> None:
    meta = load_meta(run_dir, KIND)
    config = config_from_dict(Pix2PixHDConfig, meta["config"])
    print(f"run {run_dir}: step {meta['step']}, epoch {meta['epoch']}, {config.width}x{config.height}, "
          f"held-out frames {result.frames.start}-{result.frames.stop - 1}")
    print(f"{'metric':<44}{'value':>8}")
    print(f"{'SSIM (mean)':<44}{result.ssim:>8.3f}")
    print(f"{'PSNR dB (mean)':<44}{result.psnr:>8.2f}")
    for name, value in result.pck:
        print(f"{'PCK@0.1 ' + name:<44}{value:>8.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--frames", type=int, default=0, help="score only the first N held-out frames (0: all)")
    parser.add_argument("--ground-truth", type=Path, help="true joints of the target video (synthetic target)")
    parser.add_argument("--save-video", type=Path, help="also write real | generated side by side")
    parser.add_argument("--device", default="auto")
    parser.add_argument("--threads", type=int)
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    result = held_out_quality(args.run_dir, args.frames, args.device, args.ground_truth)
    if args.save_video:
        height, width = result.generated[0].shape[:2]
        with VideoWriter(args.save_video, result.commanded.fps, 2 * width, height) as writer:
            for g, r in zip(result.generated, result.reals):
                writer.write(np.concatenate([r, g], axis=1))
    print_quality(args.run_dir, result)


if __name__ == "__main__":
    main()
