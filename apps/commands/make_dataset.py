"""`dancesynth make-dataset`: generate the built-in paired music + dance dataset."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import non_negative_int, output_folder, positive_float, positive_int

NAME = "make-dataset"
HELP = "generate synthetic songs and the dances performed to them (the built-in training data)"
DESCRIPTION = """\
Generate a dataset of paired songs and dances in three styles that differ in tempo, sound and moves:
  ballet  60-80 BPM, soft strings, plucked bass and a flute; slow arm arcs, plies, tendus, leans
  hiphop  90-105 BPM, heavy kick and snare, 808 bass, electric piano; knee bounces, arm hits, points, steps
  pop     115-135 BPM, four-on-the-floor, synth bass, bright stabs; claps, jumps, arm pumps, jumping jacks
Every song has its own tempo, key, chord progression, melody and drum variations; every dance its own body
proportions, position and sequence of moves (varied in amplitude, side and beats per move). Dancers hit
beats (stop or turn on them) but not every beat. Styles rotate over clips; songs are split 80/10/10 into
train/val/test, stratified by style. The same --seed gives the same dataset.

Output folder DIR:
  manifest.json     version, fps (15), sample_rate (22050), styles, clips [{id, song, style, split, audio,
                    poses, beats}] with paths relative to DIR
  audio/<id>.wav    the song, mono 16-bit
  poses/<id>.npz    the dance: BODY_25 keypoints [frames, 25, 3] (x, y pixels of 1280x720, confidence 1)
                    at 15 fps, frames = floor(seconds * 15); read with PoseSequence.load
  beats/<id>.json   exact beat and downbeat times in seconds and the tempo in BPM
Audio features for training are computed later, on first use, into DIR/features/<kind>/.

examples:
  dancesynth make-dataset --out data/synth
  dancesynth make-dataset --out /tmp/tiny --clips 6 --seconds 10 --seed 3
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=output_folder, required=True, metavar="DIR",
                        help="new dataset folder (must not hold a dataset)")
    parser.add_argument("--clips", type=positive_int, default=100, metavar="N",
                        help="number of songs (default %(default)s)")
    parser.add_argument("--seconds", type=positive_float, default=60.0, metavar="S",
                        help="length of each song in seconds (default %(default)s)")
    parser.add_argument("--seed", type=non_negative_int, default=0, metavar="K",
                        help="random seed (default %(default)s)")
    parser.add_argument("--workers", type=positive_int, default=2, metavar="W",
                        help="worker processes (default %(default)s)")


def run(args: argparse.Namespace) -> None:
    from stage1_pose.data.dataset import DanceDataset
    from stage1_pose.data.make_dataset import make_dataset

    path = make_dataset(args.out, clips=args.clips, seconds=args.seconds, seed=args.seed, workers=args.workers)
    ds = DanceDataset(path.parent)
    counts = ", ".join(f"{s} {len(ds.clips(s))}" for s in ("train", "val", "test"))
    logger.info(f"wrote {path}: {len(ds.clips())} clips of {args.seconds:g} s in styles {', '.join(ds.styles)} "
                f"({counts})")
