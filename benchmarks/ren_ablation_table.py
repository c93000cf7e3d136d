"""Compare trained stage-1 runs (e.g. Ren et al.'s ablation rows) on the test songs of a dataset.

For each run and each test clip it generates a dance for the whole song (seeds 0 and 1) and prints:
  l1       mean |generated - real| in model units (torso lengths), seed 0;
  speed    mean joint speed of the generated dance in torso lengths per second (real dances: row "real");
  jerk     mean joint acceleration / mean joint speed, in 1/s (high = jittery; real dances: row "real");
  frozen   fraction of 1-s spans whose mean joint speed is below 10 % of the real dance's mean speed;
  seed_d   mean distance between the seed-0 and seed-1 dances per joint and frame (0 = ignores the seed).
Usage: python benchmarks/ren_ablation_table.py --data DIR RUN_DIR [RUN_DIR ...] [--split test]
"""

from __future__ import annotations

import argparse

import numpy as np

from dancesynth.core.motion import dance_distance, joint_speeds, mean_speed
from dancesynth.core.skeleton import normalize
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.generate import generate_from_features, load_pose_model


def _jerk(xy: np.ndarray, fps: float) -> float:
    accel = np.linalg.norm(np.diff(xy, n=2, axis=0), axis=-1).mean() * fps * fps
    return float(accel / max(mean_speed(xy, fps), 1e-9))


def _frozen(speed: np.ndarray, fps: float, threshold: float) -> float:
    per_second = [s.mean() for s in np.array_split(speed, max(1, int(len(speed) / fps)))]
    return float(np.mean(np.asarray(per_second) < threshold))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+")
    parser.add_argument("--data", required=True)
    parser.add_argument("--split", default="test")
    args = parser.parse_args()
    data = DanceDataset(args.data)
    clips = data.clips(args.split)
    fps = data.fps
    # Everything in the model units of the real dance (its own body scale), so runs compare directly.
    real = {c.id: normalize(data.load_poses(c)) for c in clips}
    real_speed = float(np.mean([mean_speed(r[0], fps) for r in real.values()]))
    real_jerk = float(np.mean([_jerk(r[0], fps) for r in real.values()]))
    print(f"{len(clips)} {args.split} clips of {args.data}")
    print(f"{'run':<28}{'l1':>8}{'speed':>8}{'jerk':>8}{'frozen':>8}{'seed_d':>8}")
    print(f"{'real':<28}{0.0:>8.3f}{real_speed:>8.3f}{real_jerk:>8.2f}{0.0:>8.2f}{'':>8}")
    for run in args.runs:
        model = load_pose_model(run, device="cpu", precision="fp32")
        rows = []
        for clip in clips:
            feats = np.asarray(data.load_features(clip, model.feature_kind))
            beats = data.load_beats(clip)["beats"]
            target, params = real[clip.id]
            a, b = (normalize(generate_from_features(model, feats, beats, seed), params.scale)[0] for seed in (0, 1))
            n = min(len(a), len(target))
            speed = joint_speeds(a, fps).mean(axis=1)
            rows.append((np.abs(a[:n] - target[:n]).mean(), speed.mean(), _jerk(a, fps),
                         _frozen(speed, fps, 0.1 * real_speed), dance_distance(a, b).joints))
        l1, speed, jerk, frozen, seed_d = np.mean(rows, axis=0)
        print(f"{run[-28:]:<28}{l1:>8.3f}{speed:>8.3f}{jerk:>8.2f}{frozen:>8.2f}{seed_d:>8.3f}")


if __name__ == "__main__":
    main()
