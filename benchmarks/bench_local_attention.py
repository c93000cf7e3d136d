"""Memory and time of Dance Revolution's music encoder (paper preset) with local O(n·k) attention versus the
full n x n attention with a band mask (what the authors' public code does), for 60 s, 4 min and 10 min of music.

Each case runs in a fresh subprocess so its peak resident memory (getrusage ru_maxrss) is its own; "encoder MB"
is that peak minus the RSS before the forward pass. Forward pass, batch 1, no gradients (generation).
Usage: python benchmarks/bench_local_attention.py [--frames 900 3600 9000] [--threads N]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

FPS = 15


def run_case(mode: str, frames: int, threads: int) -> None:
    import torch

    from stage1_pose.models.dance_revolution.model import DanceRevolutionConfig, MusicEncoder
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    encoder = MusicEncoder(DanceRevolutionConfig.preset("paper")).eval()
    for layer in encoder.layers:
        layer.attention.full = mode == "full"
    audio = torch.randn(1, frames, encoder.embed.in_features)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    with torch.no_grad():
        start = time.perf_counter()
        encoder(audio)
        seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"seconds": seconds, "peak_mb": peak, "encoder_mb": peak - before}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="+", default=[900, 3600, 9000])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--case", nargs=2, metavar=("MODE", "FRAMES"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        run_case(args.case[0], int(args.case[1]), args.threads)
        return
    print(f"paper preset encoder (d_model 256, 8 heads, k = 100, 2 layers), batch 1, {args.threads} thread(s)")
    print(f"{'frames':>7}{'music':>8}{'local s':>9}{'full s':>9}{'local MB':>10}{'full MB':>10}{'MB ratio':>10}")
    for frames in args.frames:
        res = {}
        for mode in ("local", "full"):
            proc = subprocess.run([sys.executable, __file__, "--threads", str(args.threads), "--case", mode,
                                   str(frames)], capture_output=True, text=True)
            res[mode] = json.loads(proc.stdout) if proc.returncode == 0 else None
        loc, full = res["local"], res["full"]
        full_s = f"{full['seconds']:9.2f}" if full else f"{'failed':>9}"
        full_mb = f"{full['encoder_mb']:10.0f}" if full else f"{'-':>10}"
        ratio = f"{full['encoder_mb'] / max(loc['encoder_mb'], 1):10.1f}" if full else f"{'-':>10}"
        print(f"{frames:7d}{frames / FPS / 60:7.1f}m{loc['seconds']:9.2f}{full_s}{loc['encoder_mb']:10.0f}"
              f"{full_mb}{ratio}")


if __name__ == "__main__":
    main()
