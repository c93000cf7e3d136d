"""Rendering speed of the appearance model on CPU: plain PyTorch forward vs the optimised renderer (Winograd
residual blocks compiled by OpenVINO).

For each preset and size, renders the same pose sequence twice through the full per-frame path (label map,
generator conditioned on the previous frame, uint8 frame) with the plain eval-mode forward (the reference)
and with :func:`stage2_video.render.optimize_generator` (what `dancesynth render` uses). Both are warmed up, then
timed in ``--rounds`` interleaved rounds (plain, optimised, optimised, plain, ...) so load changes on the shared
CPU hit both alike; the median round is reported. Prints frames/s, the speed-up (ratio of the medians), the
spread of the rounds and the largest pixel difference (0-255 levels) between
the two networks on identical inputs (each frame conditioned on the plain run's previous frame, so rounding
differences do not compound through the random network's recursion); "unchanged output" means <= 1.
Weights are random (speed does not depend on them).

``--synthetic-person`` times the synthetic person's renderer instead (:mod:`stage2_video.synthetic_person`, which
films the demo's and the tests' target videos): frames/s at each size, where 30 is real time for its 30-fps video.

    python benchmarks/bench_render.py                      # small and paper presets at 256 and 512 px
    python benchmarks/bench_render.py --presets small --sizes 256 --frames 30 --rounds 7 --threads 2
    python benchmarks/bench_render.py --synthetic-person --sizes 256 --frames 30
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from dancesynth.core.skeleton import PoseSequence
from stage2_video.framing import condition, whole_canvas
from stage2_video.models.pix2pixhd import Pix2PixHD, Pix2PixHDConfig, generator_channels, preset
from stage2_video.render import AppearanceModel, optimize_generator, render_frames
from stage2_video.synthetic_person import PersonAppearance, render_person
from stage2_video.training_data import to_image


def dancing_poses(frames: int, size: int) -> PoseSequence:
    """A pose swinging its limbs, filling most of a ``size`` x ``size`` canvas."""
    rng = np.random.default_rng(0)
    base = rng.uniform(0.25, 0.75, (25, 2)) * size
    kp = np.ones((frames, 25, 3), np.float32)
    kp[..., :2] = base + 0.05 * size * np.sin(np.arange(frames)[:, None, None] / 3 + rng.uniform(0, 6, (25, 2)))
    return PoseSequence(kp, 15.0, size, size)


def timed_render(model: AppearanceModel, poses: PoseSequence) -> float:
    """Frames/s of one :func:`render_frames` pass over ``poses``."""
    start = time.perf_counter()
    count = sum(1 for _ in render_frames(model, poses))
    return count / (time.perf_counter() - start)


def interleaved_fps(models: list[AppearanceModel], poses: PoseSequence, rounds: int) -> list[list[float]]:
    """Frames/s of each model in each of ``rounds`` rounds, after one untimed warm-up pass of each.

    Rounds alternate the order (A B, B A, ...) so neither model always runs right after the other's caches.
    """
    for model in models:
        timed_render(model, poses)
    fps: list[list[float]] = [[] for _ in models]
    for r in range(rounds):
        order = range(len(models)) if r % 2 == 0 else reversed(range(len(models)))
        for i in order:
            fps[i].append(timed_render(models[i], poses))
    return fps


def scene_plate(config: Pix2PixHDConfig, size: int) -> np.ndarray | None:
    """A grey ``size`` px background plate for networks conditioned on one (None otherwise)."""
    return np.full((size, size, 3), 90, np.uint8) if config.background else None


def max_step_diff(plain: AppearanceModel, fast: AppearanceModel, poses: PoseSequence) -> int:
    """Largest 0-255 difference between the two models' frames, both conditioned on plain's previous frame."""
    worst, previous = 0, None
    for keypoints in poses.keypoints:
        label = condition(keypoints, plain.framing, plain.plate)
        with torch.no_grad():
            ref = plain.step(label, previous)
        out = fast.step(label, previous)
        worst = max(worst, int(np.abs(to_image(ref[0]).astype(int) - to_image(out[0]).astype(int)).max()))
        previous = ref
    return worst


def synthetic_person_fps(poses: PoseSequence, rounds: int) -> list[float]:
    """Frames/s of :func:`render_person` over ``poses`` in each of ``rounds`` passes, after one untimed pass."""
    fps = []
    for _ in range(rounds + 1):
        start = time.perf_counter()
        count = sum(1 for _ in render_person(poses, PersonAppearance()))
        fps.append(count / (time.perf_counter() - start))
    return fps[1:]


def print_synthetic_person(sizes: list[int], frames: int, rounds: int) -> None:
    """The synthetic person renderer's frames/s at each size: median and range of the rounds."""
    print(f"{'size':>6}{'synthetic person fps':>22}{'range':>14}")
    for size in sizes:
        runs = synthetic_person_fps(dancing_poses(frames, size), rounds)
        print(f"{size:>6}{float(np.median(runs)):>22.1f}{f'{min(runs):.1f}-{max(runs):.1f}':>14}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--presets", nargs="+", default=["small", "paper"])
    parser.add_argument("--sizes", nargs="+", type=int, default=[256, 512])
    parser.add_argument("--frames", type=int, default=20, help="frames per measurement (paper preset: a quarter)")
    parser.add_argument("--rounds", type=int, default=5, help="timed rounds per network (median reported)")
    parser.add_argument("--threads", type=int, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--synthetic-person", action="store_true",
                        help="time the synthetic person's renderer at each --sizes instead of the networks")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.synthetic_person:
        print_synthetic_person(args.sizes, args.frames, args.rounds)
        return
    device = torch.device("cpu")
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads; CPU shared with other jobs: "
          "absolute numbers vary with their load, the ratio column is the comparison.")
    print(f"{'preset':<7}{'size':>6}{'plain fps':>11}{'optimised fps':>15}{'ratio':>7}{'plain range':>14}"
          f"{'optimised range':>17}{'max |diff|':>12}")
    for name in args.presets:
        for size in args.sizes:
            config = preset(name, width=size, height=size)
            torch.manual_seed(0)
            generator = Pix2PixHD(config).generator.eval()
            frames = max(4, args.frames // 4) if name == "paper" else args.frames
            poses = dancing_poses(frames, size)
            framing = whole_canvas(size, size, size, size)
            plate = scene_plate(config, size)
            plain = AppearanceModel(generator, config, framing, None, 15.0, device, (size, size), plate=plate)
            fast = AppearanceModel(optimize_generator(generator, generator_channels(config), size, size, device),
                                   config, framing, None, 15.0, device, (size, size), plate=plate)
            plain_runs, fast_runs = interleaved_fps([plain, fast], poses, args.rounds)
            plain_fps, fast_fps = float(np.median(plain_runs)), float(np.median(fast_runs))
            diff = max_step_diff(plain, fast, poses)
            spread = [f"{min(runs):.2f}-{max(runs):.2f}" for runs in (plain_runs, fast_runs)]
            print(f"{name:<7}{size:>6}{plain_fps:>11.2f}{fast_fps:>15.2f}{fast_fps / plain_fps:>7.2f}"
                  f"{spread[0]:>14}{spread[1]:>17}{diff:>12d}", flush=True)


if __name__ == "__main__":
    main()
