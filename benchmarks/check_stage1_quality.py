"""Done-criteria of a stage-1 run on held-out songs: no freezing, seed variety, movement on the music's beats.

For each of the first --clips held-out (test, then val) clips of the run's dataset (or --data), a dance of --seconds
is generated with two seeds and compared with the real dances of the held-out clips:
  * freeze: mean joint speed (pixels/s) over the last 10 s >= 50 % of the first 10 s, and >= 50 % of the real
    dances' mean speed;
  * seeds: mean distance (pixels) between the joints of the two seeds' dances, against the same distance between
    two different real dances of one style (the scale of "another dance"); the seeds differ when the gap is at
    least 10 % of that; also split into body (joints relative to the MidHip) and root (the MidHip's position on
    the canvas, i.e. where the dancer stands), since real dancers differ most in where they stand;
  * beats: beat hit rate (kinematic beats within 2 frames of a music beat, stage1_pose.metrics) against chance,
    the hit rate of the same kinematic beats after random circular shifts (same count and rhythm, random phase);
    on the beat when it beats chance by 0.10; and the mean joint speed by beat phase (tenths of the interval from
    one music beat to the next; real dances slow down on the beat).
Usage: python benchmarks/check_stage1_quality.py RUN_DIR [--data DIR] [--clips 3] [--seconds 60] [--precision auto]
"""

from __future__ import annotations

import argparse

import numpy as np

from stage1_pose.data.dataset import DanceDataset
from stage1_pose.generate import generate_dance, load_pose_model
from dancesynth.core.motion import kinematic_beats
from stage1_pose.metrics import beat_hit_rate
from dancesynth.core.skeleton import ROOT


def mean_speed(xy: np.ndarray, fps: float) -> float:
    """Mean over frames and joints of |dx/dt| in pixels per second for ``[T, 25, 2]`` pixels."""
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=-1).mean() * fps) if len(xy) > 1 else 0.0


def chance_hit_rate(kin: np.ndarray, music: np.ndarray, frames: int, rng: np.random.Generator,
                    shifts: int = 500) -> float:
    """Hit rate of ``kin`` circularly shifted by random offsets: what beat-blind movement would score."""
    rates = [beat_hit_rate((kin + s) % frames, music) for s in rng.integers(0, frames, shifts)]
    return float(np.nanmean(rates))


def speed_by_beat_phase(xy: np.ndarray, beats: np.ndarray, fps: float, bins: int = 10) -> np.ndarray:
    """Mean joint speed (pixels/s) of ``[T, 25, 2]`` pixels in ``bins`` equal parts of each interval between two
    music beats (fractional frames); NaN where a part has no frame."""
    speed = np.linalg.norm(np.diff(xy, axis=0), axis=-1).mean(1) * fps
    t = np.arange(len(speed)) + 0.5
    k = np.searchsorted(beats, t) - 1
    inside = (k >= 0) & (k < len(beats) - 1)
    phase = (t[inside] - beats[k[inside]]) / (beats[k[inside] + 1] - beats[k[inside]])
    part = np.minimum((phase * bins).astype(int), bins - 1)
    return np.array([speed[inside][part == i].mean() if (part == i).any() else np.nan for i in range(bins)])


def gaps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mean distance (pixels) between two ``[T, 25, 2]`` dances: all joints, body (relative to the MidHip), root."""
    n = min(len(a), len(b))
    a, b = a[:n], b[:n]
    body = (a - a[:, ROOT:ROOT + 1]) - (b - b[:, ROOT:ROOT + 1])
    return np.array([np.linalg.norm(a - b, axis=-1).mean(), np.linalg.norm(body, axis=-1).mean(),
                     np.linalg.norm(a[:, ROOT] - b[:, ROOT], axis=-1).mean()])


def real_pair_gap(data: DanceDataset, clips: list, frames: int) -> np.ndarray:
    """:func:`gaps` between two real dances of one style, averaged over pairs of the given clips."""
    found = [gaps(data.load_poses(a).xy[:frames], data.load_poses(b).xy[:frames])
             for i, a in enumerate(clips) for b in clips[i + 1:] if a.style == b.style]
    return np.mean(found, axis=0) if found else np.full(3, np.nan)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", metavar="RUN_DIR")
    parser.add_argument("--data", metavar="DIR", help="dataset folder (default: the one the run was trained on)")
    parser.add_argument("--clips", type=int, default=3, help="held-out clips to check (default 3)")
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--precision", default="auto", choices=("auto", "fp32", "int8"))
    parser.add_argument("--device", default="auto")
    args = parser.parse_args()

    model = load_pose_model(args.run, args.device, args.precision)
    data = DanceDataset(args.data or model.meta["data"])
    held_out = data.clips("test") + data.clips("val")
    fps = data.fps
    ten = int(10 * fps)
    frames_wanted = int(args.seconds * fps)
    real_speed = float(np.mean([mean_speed(data.load_poses(c).xy, fps) for c in held_out]))
    pair_gap = real_pair_gap(data, data.clips("train") + held_out, frames_wanted)
    rng = np.random.default_rng(0)
    print(f"run {args.run} ({model.meta['method']}, epoch {model.meta['epoch']}); real held-out mean speed "
          f"{real_speed:.1f} px/s; two real dances of one style differ by {pair_gap[0]:.1f} px on average "
          f"(body {pair_gap[1]:.1f}, root {pair_gap[2]:.1f})")
    print(f"{'clip':<16}{'dance':<8}{'speed first 10s':>16}{'speed last 10s':>15}{'last/first':>11}{'vs real':>8}"
          f"{'kin beats':>10}{'hit rate':>9}{'chance':>8}{'seed gap px (body, root)':>26}")
    verdicts, profiles = [], []
    for clip in held_out[:args.clips]:
        samples = data.load_audio(clip)[: int(args.seconds * data.sample_rate)]
        dances = [generate_dance(model, samples, data.sample_rate, seed=s) for s in (0, 1)]
        frames = len(dances[0])
        music = data.load_beats(clip)["beats"] * fps
        music = music[music < frames]
        real_xy = data.load_poses(clip).xy[:frames]
        seed_gap = gaps(dances[0].xy, dances[1].xy)
        for name, xy in [("real", real_xy)] + [(f"seed {s}", d.xy) for s, d in zip((0, 1), dances)]:
            first, last = mean_speed(xy[:ten], fps), mean_speed(xy[-ten:], fps)
            kin = kinematic_beats(xy, fps)
            hit, chance = beat_hit_rate(kin, music), chance_hit_rate(kin, music, len(xy), rng)
            gap = f"{seed_gap[0]:12.1f} ({seed_gap[1]:.1f}, {seed_gap[2]:.1f})" if name == "seed 1" else ""
            print(f"{clip.id:<16}{name:<8}{first:16.1f}{last:15.1f}{last / max(first, 1e-9):11.2f}"
                  f"{last / real_speed:8.2f}{len(kin):10d}{hit:9.2f}{chance:8.2f}{gap}")
            profiles.append(f"{clip.id:<16}{name:<8}" + "".join(f"{v:6.0f}" for v in speed_by_beat_phase(xy, music, fps)))
            if name != "real":
                verdicts.append((clip.id, name, last >= 0.5 * first and last >= 0.5 * real_speed,
                                 hit > chance + 0.1, seed_gap[0] >= 0.1 * pair_gap[0]))
    print("\nmean joint speed (px/s) by beat phase, tenths of the interval from one music beat to the next:")
    print("\n".join(profiles) + "\n")
    for clip_id, name, moving, on_beat, differs in verdicts:
        print(f"{clip_id} {name}: no freeze {'PASS' if moving else 'FAIL'}, beats above chance (+0.10) "
              f"{'PASS' if on_beat else 'FAIL'}, seeds differ (>= 10 % of a real pair) {'PASS' if differs else 'FAIL'}")


if __name__ == "__main__":
    main()
