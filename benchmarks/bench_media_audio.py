"""Speed and memory of the media, audio-feature and synthetic-person modules; prints a Markdown table.

Run: NUMBA_CACHE_DIR=.venv/numba-cache .venv/bin/python benchmarks/bench_media_audio.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import mir_eval
import numpy as np

from dancesynth.core import media
from dancesynth.core.skeleton import JOINT_INDEX, NUM_JOINTS, PoseSequence
from stage1_pose import beats as beat_tracking
from stage1_pose import music_features as music_features
from stage2_video.synthetic_person import PersonAppearance, render_person

SR = 44100


def song(seconds: float) -> np.ndarray:
    """A 120 BPM kick + off-beat hi-hat loop over a chord, mono float32 at SR."""
    t = np.arange(int(seconds * SR)) / SR
    y = 0.1 * np.sin(2 * np.pi * 220 * t) + 0.05 * np.sin(2 * np.pi * 277 * t)
    k = np.arange(int(0.15 * SR)) / SR
    kick = np.sin(2 * np.pi * (60 + 100 * np.exp(-k * 30)) * k) * np.exp(-k * 20)
    for b in np.arange(0, seconds - 0.2, 0.5):
        i = int(b * SR)
        y[i:i + len(kick)] += 0.5 * kick[:len(y) - i]
    return y.astype(np.float32)


def walking(frames: int, size: int) -> PoseSequence:
    kp = np.zeros((frames, NUM_JOINTS, 3), np.float32)
    phase = np.arange(frames) / 15.0 * 2 * np.pi
    base = {"Nose": (0, .16), "Neck": (0, .26), "RShoulder": (-.09, .27), "LShoulder": (.09, .27),
            "RElbow": (-.14, .4), "RWrist": (-.16, .53), "LElbow": (.14, .4), "LWrist": (.15, .53),
            "MidHip": (0, .55), "RHip": (-.05, .55), "LHip": (.05, .55), "RKnee": (-.06, .72),
            "RAnkle": (-.06, .89), "LKnee": (.06, .72), "LAnkle": (.06, .89), "REar": (-.03, .16), "LEar": (.03, .16)}
    for name, (x, y) in base.items():
        swing = 0.05 * np.sin(phase) * (1 if name[0] == "R" else -1) * name.endswith(("Wrist", "Ankle"))
        kp[:, JOINT_INDEX[name]] = np.stack([(0.5 + x + swing) * size, np.full(frames, y * size),
                                             np.full(frames, .9)], 1)
    return PoseSequence(kp, 15.0, size, size)


def rss_mb() -> float:
    """Current resident memory of this process in MB (Linux)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def noise_frames(count: int, size: int, samples: list[float]):
    """``count`` frames cycling through 8 different noise images; records RSS every 100 frames into ``samples``."""
    pool = [np.random.default_rng(i).integers(0, 255, (size, size, 3), np.uint8) for i in range(8)]
    for i in range(count):
        if i % 100 == 0:
            samples.append(rss_mb())
        yield pool[i % len(pool)]


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return result, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="song / video length in seconds")
    args = parser.parse_args()
    y = song(args.seconds)
    music_features.extract_features(y[:SR * 5], SR, "dance_revolution")  # numba / FFT plan warm-up
    rows = []
    for kind in music_features.FEATURE_KINDS:
        feats, dt = timed(lambda: music_features.extract_features(y, SR, kind))
        rows.append((f"extract_features {kind}", f"{args.seconds:g} s song", f"{dt:.2f} s",
                     f"{args.seconds / dt:.0f}x real time", str(feats.shape)))
    beats, dt = timed(lambda: beat_tracking.beat_times(y, SR))
    reference = np.arange(0, args.seconds - 0.2, 0.5)
    rows.append(("beat_times", f"{args.seconds:g} s song", f"{dt:.2f} s",
                 f"F={mir_eval.beat.f_measure(reference, beats):.3f}",
                 f"{beat_tracking.tempo(y, SR):.1f} BPM"))
    frames = int(args.seconds * 15)
    for size in (256, 512):
        seq = walking(frames, size)
        _, dt = timed(lambda: sum(1 for _ in render_person(seq, PersonAppearance())))
        rows.append(("render_person", f"{frames} frames {size}x{size}", f"{dt:.2f} s",
                     f"{frames / dt:.0f} frames/s", ""))
        with tempfile.TemporaryDirectory() as tmp:
            memory: list[float] = []
            path = Path(tmp) / "out.mp4"
            _, dt = timed(lambda: media.write_video(path, noise_frames(frames, size, memory), 15, audio=y, audio_sr=SR))
            streams = media.probe_streams(path)
            sync_ms = 1000 * abs(streams["audio_duration"] - streams["video_duration"])
            rows.append(("write_video + AAC", f"{frames} noise frames {size}x{size}", f"{dt:.2f} s",
                         f"{frames / dt:.0f} frames/s",
                         f"RSS growth after frame 100: {max(memory[1:]) - memory[1]:.0f} MB, "
                         f"A/V diff {sync_ms:.1f} ms"))
            _, dt = timed(lambda: sum(1 for _ in media.read_frames(path)))
            rows.append(("read_frames", f"{frames} frames {size}x{size}", f"{dt:.2f} s",
                         f"{frames / dt:.0f} frames/s", ""))
    print("| operation | input | time | rate | notes |\n|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
