"""`dancesynth prepare`: a folder of real dance videos with their soundtracks -> a stage-1 dataset."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import output_folder, positive_float
from apps.requests import BEATS

NAME = "prepare"
HELP = "turn a folder of real dance videos (style = sub-folder name) into a stage-1 training dataset"
DESCRIPTION = """\
Find every video (.mp4 .mov .m4v .mkv .avi .webm) under VIDEOS_DIR, extract the dancer's BODY_25 poses with
the bundled BlazePose (one tracked person per video, as `extract-poses` does), decode the soundtrack, cut both
into clips of about --clip-seconds and append them to the dataset folder DATASET_DIR (the layout of
`make-dataset`: 15 fps poses, 22050 Hz audio, tracked beats). A video's style is the name of its sub-folder:

  VIDEOS_DIR/salsa/take1.mp4   -> style "salsa"
  VIDEOS_DIR/tango/night.mov   -> style "tango"
  VIDEOS_DIR/loose.mp4         -> style --default-style

All clips of one video share a train/val/test split (80/10/10 by song). Re-running after adding videos adds
only the new ones. Videos without sound, without one clearly visible person, or unreadable are skipped with
the reason; the command fails only when no video could be used. Needs the `pose` extra (mediapipe).

examples:
  dancesynth prepare my_dances/ --out data/my_dances
  dancesynth prepare my_dances/ --out data/my_dances --clip-seconds 30
  dancesynth train-pose --method dance_revolution --data data/my_dances --out runs/my_dr
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("videos_dir", metavar="VIDEOS_DIR", help="folder of dance videos, one sub-folder per style")
    parser.add_argument("--out", type=output_folder, required=True, metavar="DATASET_DIR",
                        help="dataset folder to create or add to")
    parser.add_argument("--clip-seconds", type=positive_float, default=60.0,
                        help="length of the clips each video is cut into, in seconds (default 60)")
    parser.add_argument("--default-style", default="dance",
                        help="style of the videos directly in VIDEOS_DIR (default 'dance')")
    BEATS.add_to(parser, "beats")


def run(args: argparse.Namespace) -> None:
    from apps.prepare import prepare_videos
    from dancesynth.core.errors import DancesynthError
    from dancesynth.core.fileio import check_outputs

    check_outputs({}, {"videos folder": args.videos_dir}, folders={"dataset folder": args.out})
    report = prepare_videos(args.videos_dir, args.out, args.clip_seconds, args.default_style, tracker=args.beats)
    for video, reason in report.skipped.items():
        logger.warning(f"skipped {video}: {reason}")
    if not report.added and not report.already_there:
        raise DancesynthError(f"None of the videos in {args.videos_dir} could be used (reasons above); use videos "
                              "with a soundtrack and one clearly visible dancer.")
    logger.info(f"added {len(report.added)} clips ({len(report.already_there)} were there already) to "
                f"{args.out}; train on it with `dancesynth train-pose --data {args.out} ...`")
