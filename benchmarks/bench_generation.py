"""Seconds and peak RSS to generate 60 s and 4 min of dance with Dance Revolution's paper preset on CPU, batch 1.

Random weights (speed does not depend on them) and random features: this times the model - music encoder and
the 3 x 1024 LSTM decoder stepping frame by frame - not audio feature extraction. Every case runs in a fresh
subprocess: "peak MB" is the process's whole peak resident memory (Python, torch, model and all).
Targets on the 2-core development machine: 60 s in <= 2.4 s, 4 min in <= 600 MB (the authors' code: 7.2 s, 1.9 GB).
Usage: python benchmarks/bench_generation.py [--threads 1 2] [--precisions fp32 int8]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

FPS = 15


def run_case(seconds: float, precision: str, threads: int) -> None:
    import torch

    from stage1_pose.models.dance_revolution.model import DanceRevolution, DanceRevolutionConfig
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    model = DanceRevolution(DanceRevolutionConfig.preset("paper")).eval()
    start = time.perf_counter()
    model.prepare_inference(precision)
    prepare = time.perf_counter() - start
    features = torch.randn(1, int(seconds * FPS), model.config.feature_dim)
    beats = torch.zeros(features.shape[:2], dtype=torch.bool)
    beats[:, ::8] = True  # 112.5 BPM
    start = time.perf_counter()
    poses = model.generate(features, beats, torch.Generator().manual_seed(0))
    took = time.perf_counter() - start
    assert poses.shape[1] == features.shape[1]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"seconds": took, "prepare": prepare, "peak_mb": peak}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--precisions", nargs="+", default=["fp32", "int8"])
    parser.add_argument("--case", nargs=3, metavar=("SECONDS", "PRECISION", "THREADS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        run_case(float(args.case[0]), args.case[1], int(args.case[2]))
        return
    print("Dance Revolution paper preset (encoder 2 x 256, LSTM 3 x 1024), CPU, batch 1")
    print(f"{'dance':>7}{'precision':>10}{'threads':>8}{'generate s':>11}{'x realtime':>11}{'prepare s':>10}"
          f"{'peak MB':>9}")
    for seconds in (60.0, 240.0):
        for precision in args.precisions:
            for threads in args.threads:
                proc = subprocess.run([sys.executable, __file__, "--case", str(seconds), precision, str(threads)],
                                      capture_output=True, text=True)
                if proc.returncode != 0:
                    print(f"{seconds:6.0f}s{precision:>10}{threads:8d}  failed: {proc.stderr.strip()[-200:]}")
                    continue
                r = json.loads(proc.stdout)
                print(f"{seconds:6.0f}s{precision:>10}{threads:8d}{r['seconds']:11.2f}{seconds / r['seconds']:11.1f}"
                      f"{r['prepare']:10.2f}{r['peak_mb']:9.0f}")


if __name__ == "__main__":
    main()
