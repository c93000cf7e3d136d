"""The appearance model on poses it never saw, scored against the truth: the demo's synthetic person dancing.

A real clip's held-out frames are poses its person really took; a dance asks for new ones, and only a synthetic
person can be drawn at them. This runs `make demo`'s steps in ``--out`` (built-in songs, the synthetic target video,
its appearance model trained ``--minutes``; kept and reused when they are there), has the model dance ``--seconds``
of the held-out built-in song ``--song``, draws the synthetic person at the dance's poses and prints box SSIM and
PSNR (:func:`stage2_video.quality.box_scores`: the person's box grown by a margin) over every frame and over the
lowest ten: what a flap of hip swinging with an arm, or a tooth of torso left under it, costs.

    python benchmarks/synthetic_dance.py --out /tmp/synth --minutes 2
    python benchmarks/synthetic_dance.py --out /tmp/synth            # the same model again, after a change to the warp
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from apps.demo import DEMO_LOOK, run_demo
from apps.pipeline import dance
from apps.requests import DanceRequest
from dancesynth.core.checkpoint import has_checkpoint
from dancesynth.core.media import read_frames
from dancesynth.core.skeleton import PoseSequence, body_scale
from stage2_video.quality import box_scores
from stage2_video.synthetic_person import appearance_preset, render_person

LOWEST = 10


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True, help="the demo's folder (made when absent, else reused)")
    ap.add_argument("--minutes", type=float, default=2.0, help="the demo's minutes when it is made")
    ap.add_argument("--song", default="pop_00008", help="a built-in song's name")
    ap.add_argument("--seconds", type=float, default=12.0, help="seconds of the song danced")
    ap.add_argument("--seed", type=int, default=3, help="the dance's seed")
    args = ap.parse_args(argv)
    run = args.out / "runs" / "video"
    if not has_checkpoint(run):
        run_demo(args.out, args.minutes, device="cpu")
    songs = sorted((args.out / "dataset").rglob(f"{args.song}.wav"))
    if not songs:
        print(f"no built-in song {args.song!r} in {args.out / 'dataset'}", file=sys.stderr)
        return 1
    video = args.out / "synthetic_dance.mp4"
    made = dance(DanceRequest(song=songs[0], out=video, video_model=run, seed=args.seed, duration=args.seconds,
                              device="cpu"))
    frames = list(read_frames(video))
    target = PoseSequence.load(args.out / "target" / "target_poses.npz")
    size = (frames[0].shape[1], frames[0].shape[0])
    truth = render_person(made.poses, appearance_preset(DEMO_LOOK), size, body_scale(target))
    scores = np.array([box_scores(frame, real, kp) for frame, real, kp in zip(frames, truth, made.poses.keypoints)])
    lowest = np.sort(scores[:, 0])[:LOWEST].mean()
    print(f"{len(scores)} frames of {args.song} (seed {args.seed}) against the synthetic truth: box SSIM "
          f"{scores[:, 0].mean():.4f}, PSNR {scores[:, 1].mean():.2f} dB; the lowest {LOWEST} frames' SSIM "
          f"{lowest:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
