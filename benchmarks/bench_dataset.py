"""Built-in dataset: generation time, how well a beat tracker finds the songs' beats, how well dances hit them.

Generates ``--clips`` songs of ``--seconds`` seconds (default: the full 100 x 60 s dataset) into a temporary
folder (or ``--out``), timing :func:`stage1_pose.data.make_dataset.make_dataset`. Then, per style:

* ``beat F``: F-measure (+-70 ms) of :func:`stage1_pose.beats.beat_times` on each song against the exact beats
  the song was synthesised with (mean and minimum over songs);
* ``KB hit`` / ``VM hit``: fraction of the dance's kinematic beats (Dancing2Music offsets /
  velocity minima) within +-1 pose frame of a music beat, and ``chance``: the same for the Dancing2Music beats
  shifted by random offsets (:func:`dancesynth.core.motion.chance_hit_rate`).

    .venv/bin/python benchmarks/bench_dataset.py                          # 100 clips x 60 s
    .venv/bin/python benchmarks/bench_dataset.py --clips 12 --seconds 20  # quick look
"""

from __future__ import annotations

import argparse
import multiprocessing
import tempfile
import time
from pathlib import Path

import mir_eval
import numpy as np

from dancesynth.core.motion import chance_hit_rate, kinematic_beats, velocity_minimum_beats
from dancesynth.core.skeleton import normalize
from stage1_pose.beats import beat_times
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.data.make_dataset import make_dataset
from stage1_pose.metrics import beat_hit_rate


def _score(job: tuple[str, int]) -> tuple[str, float, float, float, float]:
    root, index = job
    ds = DanceDataset(root)
    clip = ds.clips()[index]
    reference = ds.load_beats(clip)["beats"]
    f = mir_eval.beat.f_measure(reference, beat_times(ds.load_audio(clip), ds.sample_rate), 0.07)
    poses = ds.load_poses(clip)
    xy = normalize(poses)[0]
    beat_frames = np.round(reference * ds.fps).astype(np.int64)
    kb, vm = kinematic_beats(xy, ds.fps), velocity_minimum_beats(xy, ds.fps)
    rng = np.random.default_rng(index)
    chance = chance_hit_rate(kb, beat_frames, len(poses), rng, tolerance_frames=1)
    return (clip.style, f, beat_hit_rate(kb, beat_frames, tolerance_frames=1),
            beat_hit_rate(vm, beat_frames, tolerance_frames=1), chance)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=100)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, help="keep the dataset here (default: a temporary folder)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp) / "ds"
        start = time.perf_counter()
        make_dataset(root, clips=args.clips, seconds=args.seconds, workers=args.workers)
        took = time.perf_counter() - start
        with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
            rows = pool.map(_score, [(str(root), i) for i in range(args.clips)])
    print(f"\nmake_dataset: {args.clips} clips x {args.seconds:g} s with {args.workers} workers in {took:.1f} s\n")
    print(f"{'style':8} {'clips':>5} {'beat F mean':>11} {'beat F min':>10} {'KB hit':>7} {'VM hit':>7} {'chance':>7}")
    for style in sorted({r[0] for r in rows}) + ["all"]:
        sel = np.array([r[1:] for r in rows if style in ("all", r[0])])
        print(f"{style:8} {len(sel):5d} {sel[:, 0].mean():11.3f} {sel[:, 0].min():10.3f} "
              f"{np.nanmean(sel[:, 1]):7.2f} {np.nanmean(sel[:, 2]):7.2f} {sel[:, 3].mean():7.2f}")


if __name__ == "__main__":
    main()
