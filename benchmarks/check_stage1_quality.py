"""Done-criteria of a stage-1 run on a held-out song: no freezing, seed variety, movement on the music's beats.

For the first test clip of the run's dataset (or --data), a dance of --seconds is generated with two seeds and
compared with the real dances of the held-out (test + val) clips:
  * freeze: mean joint speed (pixels/s) over the last 10 s >= 50 % of the first 10 s, and >= 50 % of the real
    dances' mean speed;
  * seeds: mean distance (pixels) between the joints of the two seeds' dances > 0;
  * beats: beat hit rate (kinematic beats within 2 frames of a music beat, stage1_pose.metrics) against chance,
    the hit rate of the same kinematic beats after random circular shifts (same count and rhythm, random phase).
Usage: python benchmarks/check_stage1_quality.py RUN_DIR [--data DIR] [--seconds 60] [--precision auto]
"""

from __future__ import annotations

import argparse

import numpy as np

from stage1_pose.data.dataset import DanceDataset
from stage1_pose.generate import generate_dance, load_pose_model
from stage1_pose.kinematic_beats import kinematic_beats
from stage1_pose.metrics import beat_hit_rate


def mean_speed(xy: np.ndarray, fps: float) -> float:
    """Mean over frames and joints of |dx/dt| in pixels per second for ``[T, 25, 2]`` pixels."""
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=-1).mean() * fps) if len(xy) > 1 else 0.0


def chance_hit_rate(kin: np.ndarray, music: np.ndarray, frames: int, rng: np.random.Generator,
                    shifts: int = 500) -> float:
    """Hit rate of ``kin`` circularly shifted by random offsets: what beat-blind movement would score."""
    rates = [beat_hit_rate((kin + s) % frames, music) for s in rng.integers(0, frames, shifts)]
    return float(np.nanmean(rates))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", metavar="RUN_DIR")
    parser.add_argument("--data", metavar="DIR", help="dataset folder (default: the one the run was trained on)")
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--precision", default="auto", choices=("auto", "fp32", "int8"))
    parser.add_argument("--device", default="auto")
    args = parser.parse_args()

    model = load_pose_model(args.run, args.device, args.precision)
    data = DanceDataset(args.data or model.meta["data"])
    held_out = data.clips("test") + data.clips("val")
    clip = held_out[0]
    fps = data.fps
    samples = data.load_audio(clip)[: int(args.seconds * data.sample_rate)]
    dances = [generate_dance(model, samples, data.sample_rate, seed=s) for s in (0, 1)]
    frames = len(dances[0])
    ten = int(10 * fps)
    music = data.load_beats(clip)["beats"] * fps
    music = music[music < frames]
    real_speed = float(np.mean([mean_speed(data.load_poses(c).xy, fps) for c in held_out]))
    real_xy = data.load_poses(clip).xy[:frames]
    real_kin = kinematic_beats(real_xy, fps)
    rng = np.random.default_rng(0)

    print(f"run {args.run} ({model.meta['method']}, epoch {model.meta['epoch']}), held-out clip {clip.id} "
          f"({clip.style}), {frames / fps:.0f} s, {len(music)} music beats")
    print(f"{'dance':<8}{'speed first 10s':>16}{'speed last 10s':>15}{'last/first':>11}{'vs real':>8}"
          f"{'kin beats':>10}{'hit rate':>9}{'chance':>8}")
    checks = []
    for name, xy in [("real", real_xy)] + [(f"seed {s}", d.xy) for s, d in zip((0, 1), dances)]:
        first, last = mean_speed(xy[:ten], fps), mean_speed(xy[-ten:], fps)
        kin = real_kin if name == "real" else kinematic_beats(xy, fps)
        hit, chance = beat_hit_rate(kin, music), chance_hit_rate(kin, music, len(xy), rng)
        print(f"{name:<8}{first:16.1f}{last:15.1f}{last / max(first, 1e-9):11.2f}{last / real_speed:8.2f}"
              f"{len(kin):10d}{hit:9.2f}{chance:8.2f}")
        if name != "real":
            checks.append((name, last >= 0.5 * first and last >= 0.5 * real_speed, hit > chance + 0.1))
    seed_gap = float(np.linalg.norm(dances[0].xy - dances[1].xy, axis=-1).mean())
    print(f"real held-out mean speed {real_speed:.1f} px/s; seeds 0 vs 1 differ by {seed_gap:.1f} px on average")
    for name, moving, on_beat in checks:
        print(f"{name}: no freeze {'PASS' if moving else 'FAIL'}, beats above chance (+0.10) "
              f"{'PASS' if on_beat else 'FAIL'}")
    print(f"seeds differ: {'PASS' if seed_gap > 1.0 else 'FAIL'}")


if __name__ == "__main__":
    main()
