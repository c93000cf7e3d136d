"""Smoothness of the frame-rate conversion of a dance (`dance` resamples 15 fps -> the target's fps).

Prints the mean jerk (px/s^3, :func:`dancesynth.core.motion.mean_jerk`) of a built-in 20-s dance converted from
15 to 30 fps by linear interpolation (the former path) and by :func:`dancesynth.core.skeleton.resample` (PCHIP).

    python benchmarks/bench_resample.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from dancesynth.core.motion import mean_jerk
from dancesynth.core.skeleton import PoseSequence, resample
from stage1_pose.data.make_dataset import make_dataset

FPS = 30.0


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        make_dataset(Path(tmp) / "ds", clips=1, seconds=20, workers=1, progress=False)
        seq = PoseSequence.load(next((Path(tmp) / "ds" / "poses").glob("*.npz")))
    src, dst = np.arange(len(seq)) / seq.fps, np.arange(round(seq.duration * FPS)) / FPS
    linear = np.stack([np.interp(dst, src, c) for c in seq.xy.reshape(len(seq), -1).T], 1).reshape(-1, 25, 2)
    print(f"{seq.fps:g} fps -> {FPS:g} fps, {seq.duration:g} s, canvas {seq.width}x{seq.height}")
    print(f"mean jerk: linear {mean_jerk(linear, FPS):.0f} px/s^3, PCHIP {mean_jerk(resample(seq, FPS).xy, FPS):.0f} "
          "px/s^3")


if __name__ == "__main__":
    main()
