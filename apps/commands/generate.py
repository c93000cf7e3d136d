"""`dancesynth generate`: a dance (pose sequence) for a song, from a trained stage-1 run."""

from __future__ import annotations

import argparse

NAME = "generate"
HELP = "generate a dance (BODY_25 pose sequence) for a song with a trained pose model"
DESCRIPTION = """\
Generate a dance for SONG (any audio file, any length) with a model trained by `dancesynth train-pose`.
The output .npz holds keypoints [T, 25, 3] (x, y in pixels of the training canvas, confidence 1), fps, width,
height; T = song length x fps. Another --seed gives another dance (for stochastic methods).
--preview writes a skeleton video with the song as its soundtrack.

examples:
  dancesynth generate song.mp3 --model runs/dr --out poses.npz
  dancesynth generate song.mp3 --model runs/dr --out poses.npz --seed 3 --preview preview.mp4
"""

SONG_SR = 22050


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("song", metavar="SONG", help="audio file (mp3, wav, m4a, ... or a video's soundtrack)")
    parser.add_argument("--model", required=True, metavar="RUN_DIR", help="run folder from dancesynth train-pose")
    parser.add_argument("--out", required=True, metavar="POSES.npz", help="output pose file")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the dance (default 0)")
    parser.add_argument("--preview", metavar="VIDEO.mp4", help="also write a skeleton preview video with the song")
    parser.add_argument("--precision", default="auto", choices=("auto", "fp32", "int8"),
                        help="decoder weights: int8 is ~3x faster on CPU; auto = int8 on CPU, fp32 on GPU")
    parser.add_argument("--device", default="auto", help="auto, cpu or cuda")


def run(args: argparse.Namespace) -> None:
    from dancesynth.core.draw import write_skeleton_video
    from stage1_pose.generate import generate_dance, load_pose_model
    from dancesynth.core.media import load_song

    model = load_pose_model(args.model, args.device, args.precision)
    samples = load_song(args.song, SONG_SR)
    seq = generate_dance(model, samples, SONG_SR, seed=args.seed)
    seq.save(args.out)
    if args.preview:
        write_skeleton_video(seq, args.preview, audio=samples, audio_sr=SONG_SR)
    print(f"wrote {args.out}: {len(seq)} frames at {seq.fps:g} fps ({seq.duration:.1f} s), "
          f"{seq.width}x{seq.height} canvas" + (f"; preview {args.preview}" if args.preview else ""))
