"""Peak memory and wall time of `dancesynth dance` for a 30-s and a 3-min song (fresh process each).

Usage: python benchmarks/bench_dance.py --pose-model RUN --video-model RUN   (e.g. the runs `make demo` wrote:
demo_output/runs/pose and demo_output/runs/video). Memory must not grow with song length:
frames stream to the encoder, so only the song samples and the pose array scale with duration.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import soundfile

from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_music import synthesize_song


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pose-model", required=True)
    ap.add_argument("--video-model", required=True)
    ap.add_argument("--seconds", type=float, nargs="+", default=[30.0, 180.0])
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seconds in args.seconds:
            song = synthesize_song(STYLES["pop"], seconds, np.random.default_rng(0))
            wav = Path(tmp) / f"song_{seconds:g}.wav"
            soundfile.write(wav, song.samples, song.sample_rate)
            start = time.perf_counter()
            child = subprocess.Popen([sys.executable, "-m", "apps.cli", "dance", str(wav), "--pose-model",
                                      args.pose_model, "--video-model", args.video_model, "--out",
                                      str(Path(tmp) / "out.mp4")], stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
            # wait4 gives this child's own peak RSS (RUSAGE_CHILDREN would be the maximum over all children).
            _, status, usage = os.wait4(child.pid, 0)
            wall = time.perf_counter() - start
            if os.waitstatus_to_exitcode(status) != 0:
                raise SystemExit(f"dance failed on the {seconds:g}-s song; run it by hand to see why.")
            rows.append((seconds, wall, usage.ru_maxrss / 1024))
    print(f"{'song s':>8} {'wall s':>8} {'peak RSS MB':>12}  {'x real time':>11}")
    for seconds, wall, peak_mb in rows:
        print(f"{seconds:8.0f} {wall:8.1f} {peak_mb:12.0f}  {seconds / wall:11.2f}")


if __name__ == "__main__":
    main()
