"""Dancing2Music done-criteria on held-out songs: continuity across unit boundaries and beat hits.

For every test-split song (the first ``--seconds`` seconds) it generates ``--seeds`` dances with each trained run and
compares them with the real dances:

* continuity: the largest frame-to-frame joint displacement in torso lengths (each dance normalised by its own body
  scale), against the 99th percentile of the same quantity over the real train-split dances;
* beats: beat hit rate (share of kinematic beats within 2 frames of a tracked music beat) and beat coverage
  (kinematic beats per music beat), Lee et al. 2019 Sec. 4, with the music beats tracked on the audio
  (:func:`stage1_pose.beats.beat_times`) for real and generated dances alike.

Each run is measured through :func:`stage1_pose.generate.generate_dance` as users get it (the song's tracked
beats go to the model's beat warper), and with the paper's warper (normalised unit beats on the music beats, no
accent) in place of the run's.

Usage: python benchmarks/bench_dancing2music.py --data DATA_DIR --model RUN_DIR [--model RUN_DIR2 ...]
       [--seconds 60] [--seeds 3] [--device auto]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from dancesynth.core.motion import joint_speeds, kinematic_beats
from dancesynth.core.skeleton import PoseSequence, interpolate_missing, normalize
from stage1_pose.beats import beat_times
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.generate import generate_dance, load_pose_model
from stage1_pose.metrics import beat_hit_rate
from stage1_pose.models.kinematics import absolute_positions


def frame_jumps(seq: PoseSequence) -> np.ndarray:
    """``[T - 1]`` largest joint displacement between consecutive frames, in torso lengths."""
    xy = absolute_positions(normalize(seq)[0])
    return joint_speeds(xy, seq.fps).max(axis=1) / seq.fps


def beat_scores(seq: PoseSequence, music_beats_s: np.ndarray) -> tuple[int, int, int]:
    """(kinematic beats, music beats, aligned kinematic beats) of a dance over its own duration."""
    music = music_beats_s[music_beats_s < seq.duration] * seq.fps
    kin = np.asarray(kinematic_beats(seq.xy, seq.fps))
    hits = int(round(beat_hit_rate(kin, music) * len(kin))) if len(kin) else 0
    return len(kin), len(music), hits


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", required=True, help="dataset folder (dancesynth make-dataset)")
    parser.add_argument("--model", action="append", required=True, help="trained dancing2music run folder")
    parser.add_argument("--seconds", type=float, default=60.0, help="length of each song excerpt")
    parser.add_argument("--seeds", type=int, default=3, help="dances generated per song and model")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")
    args = parser.parse_args()

    ds = DanceDataset(args.data)
    real_train = [interpolate_missing(ds.load_poses(c)) for c in ds.clips("train")]
    threshold = float(np.percentile(np.concatenate([frame_jumps(s) for s in real_train]), 99))

    songs = []
    for clip in ds.clips("test"):
        real = interpolate_missing(ds.load_poses(clip))
        real = real.slice_frames(0, min(len(real), int(args.seconds * real.fps)))
        samples = ds.load_audio(clip)[: int(args.seconds * ds.sample_rate)]
        songs.append((clip.id, real, samples, beat_times(samples, ds.sample_rate)))

    rows = [("real (test)", [s[1] for s in songs], [s[3] for s in songs])]
    for run in args.model:
        model = load_pose_model(run, args.device)
        own = model.method.config
        for label, config in (("tracked beats", own),
                              ("paper warper", replace(own, warp_stretch=1.0, beat_accent=0.0))):
            model.method.config = config
            dances, beats = [], []
            for _, _, samples, music in songs:
                for seed in range(args.seeds):
                    dances.append(generate_dance(model, samples, ds.sample_rate, seed=seed))
                    beats.append(music)
            rows.append((f"{Path(run).name} {label}", dances, beats))

    print(f"real train-split 99th percentile of per-frame max joint jump: {threshold:.3f} torso lengths")
    print(f"{'dances':<32}{'n':>4}{'max jump':>10}{'p99 jump':>10}{'>thr %':>8}{'hit rate':>10}{'coverage':>10}")
    for name, dances, music in rows:
        jumps = np.concatenate([frame_jumps(d) for d in dances])
        k, m, a = np.sum([beat_scores(d, b) for d, b in zip(dances, music)], axis=0)
        print(f"{name:<32}{len(dances):>4}{jumps.max():>10.3f}{np.percentile(jumps, 99):>10.3f}"
              f"{100 * np.mean(jumps > threshold):>8.2f}{a / max(k, 1):>10.3f}{k / max(m, 1):>10.3f}")


if __name__ == "__main__":
    main()
