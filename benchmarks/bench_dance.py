"""Wall time (and peak memory) of the main job, each command in a fresh process.

    python benchmarks/bench_dance.py --video-model RUN [--pose-model RUN]   # by song length: 30 s and 3 min
    python benchmarks/bench_dance.py --target VIDEO [--train-minutes 0.5]   # dance --target: training, then cached
    python benchmarks/bench_dance.py --demo 3                               # dancesynth demo: against its budget

By song length (e.g. with the runs `make demo` wrote: demo_output/runs/pose and demo_output/runs/video): memory
must not grow with song length, since frames stream to the encoder and only the song samples and the pose array
scale with duration. ``--target``: the first call trains the video's appearance model into a fresh cache for
``--train-minutes``, the second finds it there and should start rendering at once (its time about the
video-model row's for the same song). ``--demo M``: `dancesynth demo --minutes M`, whose training shares the
budget so only its fixed dance and summary steps run past it, then the same command again, which reuses every
model and data file and so takes a fraction of it.
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


def run(argv: list[str]) -> tuple[float, float]:
    """(wall seconds, peak RSS in MB) of `dancesynth ARGV` in a fresh process; exits when the command fails."""
    start = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-m", "apps.cli", *argv], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    # wait4 gives this child's own peak RSS (RUSAGE_CHILDREN would be the maximum over all children).
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"`dancesynth {' '.join(argv)}` failed; run it by hand to see why.")
    return wall, usage.ru_maxrss / 1024


def song(folder: Path, seconds: float) -> Path:
    """A synthesised pop song of ``seconds`` as a wav file in ``folder``."""
    made = synthesize_song(STYLES["pop"], seconds, np.random.default_rng(0))
    path = folder / f"song_{seconds:g}.wav"
    soundfile.write(path, made.samples, made.sample_rate)
    return path


def by_song_length(tmp: Path, args: argparse.Namespace) -> None:
    """Wall time and peak memory of `dance --video-model` for each of ``--seconds``."""
    pose = ["--pose-model", args.pose_model] if args.pose_model else []
    print(f"{'song s':>8} {'wall s':>8} {'peak RSS MB':>12}  {'x real time':>11}")
    for seconds in args.seconds:
        wall, peak_mb = run(["dance", str(song(tmp, seconds)), *pose, "--video-model", args.video_model, "--out",
                             str(tmp / "out.mp4")])
        print(f"{seconds:8.0f} {wall:8.1f} {peak_mb:12.0f}  {seconds / wall:11.2f}", flush=True)


def cached_target(tmp: Path, args: argparse.Namespace) -> None:
    """Wall time of `dance --target` training a fresh cache entry, then of the same call finding it cached."""
    pose = ["--pose-model", args.pose_model] if args.pose_model else []
    call = ["dance", str(song(tmp, args.seconds[0])), *pose, "--target", args.target, "--cache", str(tmp / "cache"),
            "--train-minutes", f"{args.train_minutes:g}", "--out", str(tmp / "out.mp4")]
    print(f"{'dance --target':<32}{'wall s':>8}")
    for what in (f"training {args.train_minutes:g} min, then", "cached model"):
        print(f"{what:<32}{run(call)[0]:>8.1f}", flush=True)


def demo(tmp: Path, minutes: float) -> None:
    """Wall time of `dancesynth demo --minutes` against its budget, then of the same command again."""
    call = ["demo", "--out", str(tmp / "demo"), "--minutes", f"{minutes:g}"]
    print(f"{'demo':<10}{'wall s':>8}{'budget s':>10}{'wall/budget':>13}")
    for what in ("first", "again"):
        wall = run(call)[0]
        print(f"{what:<10}{wall:>8.1f}{minutes * 60:>10.0f}{wall / (minutes * 60):>13.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--video-model", help="time `dance --video-model RUN` by song length")
    what.add_argument("--target", help="time `dance --target VIDEO` training, then cached")
    what.add_argument("--demo", type=float, metavar="MINUTES", help="time `dancesynth demo --minutes MINUTES`")
    ap.add_argument("--pose-model", help="stage-1 run (default: the shipped pose model)")
    ap.add_argument("--seconds", type=float, nargs="+", default=[30.0, 180.0],
                    help="song lengths (--target: the first only)")
    ap.add_argument("--train-minutes", type=float, default=0.5, help="--target's training budget")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.video_model:
            by_song_length(Path(tmp), args)
        elif args.target:
            cached_target(Path(tmp), args)
        else:
            demo(Path(tmp), args.demo)


if __name__ == "__main__":
    main()
