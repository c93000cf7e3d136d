"""`dancesynth import-dance`: add a recorded dance and its song to a dataset folder."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import (
    existing_file,
    non_negative_int,
    output_folder,
    positive_float,
    positive_int,
)
from apps.requests import BEATS

NAME = "import-dance"
HELP = "add a recorded dance (OpenPose JSON folder or AIST++ keypoints) and its song to a dataset folder"
DESCRIPTION = """\
Append one clip to the dataset folder DIR (created when it does not exist): the dance is resampled to 15 fps,
the song decoded to 22050 Hz mono, both trimmed to their common length, and the song's beats tracked
(beats/<id>.json gets "source": "tracked"). Dances to the same song (same samples) share its train/val/test
split; a new song gets a stable 80/10/10 split by its hash unless --split is given.

Sources:
  --openpose FOLDER   OpenPose *_keypoints.json files, one per video frame (BODY_25 or COCO-18); give the
                      video's --fps, --width and --height, which OpenPose does not store.
  --aistpp FILE       AIST++ 2D keypoints converted to .npy/.npz: [views, T, 17, 3] or [T, 17, 3] COCO-17
                      at 60 fps on 1920x1080 (override with --fps/--width/--height). The release's .pkl
                      files are never unpickled here; convert once in a Python session you trust:
                        import pickle, numpy as np
                        np.save("seq.npy", pickle.load(open("seq.pkl", "rb"))["keypoints2d"])
                      --style defaults to the genre in the name (gBR_... -> break).

examples:
  dancesynth import-dance --out data/mine --openpose take1_json/ --fps 30 --width 1920 --height 1080 \\
      --audio take1.mp4 --style salsa
  dancesynth import-dance --out data/aist --aistpp gBR_sBM_cAll_d04_mBR0_ch01.npy --audio mBR0.mp3
"""

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=output_folder, required=True, metavar="DIR",
                        help="dataset folder to add to (created if new)")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--openpose", metavar="FOLDER", help="folder of OpenPose *_keypoints.json files")
    source.add_argument("--aistpp", type=existing_file, metavar="FILE",
                        help="AIST++ 2D keypoints converted to .npy or .npz")
    parser.add_argument("--audio", type=existing_file, required=True, metavar="SONG",
                        help="the song (any FFmpeg-readable file)")
    parser.add_argument("--style", help="style label (required for --openpose)")
    parser.add_argument("--fps", type=positive_float, help="frame rate of the keypoints (AIST++ default 60)")
    parser.add_argument("--width", type=positive_int, help="video width in pixels (AIST++ default 1920)")
    parser.add_argument("--height", type=positive_int, help="video height in pixels (AIST++ default 1080)")
    parser.add_argument("--view", type=non_negative_int, default=0,
                        help="camera of a multi-view AIST++ array (default 0)")
    parser.add_argument("--id", dest="clip_id", help="clip id (default: the folder or file name)")
    parser.add_argument("--split", choices=("train", "val", "test"), help="split (default: by song)")
    BEATS.add_to(parser, "beats")


def run(args: argparse.Namespace) -> None:
    from dancesynth.core.errors import DancesynthError
    from dancesynth.core.fileio import check_outputs
    from stage1_pose.data import importers

    check_outputs({}, {"OpenPose folder": args.openpose, "AIST++ file": args.aistpp, "song": args.audio},
                  folders={"dataset folder": args.out})
    if args.openpose:
        missing = [f"--{k}" for k in ("style", "fps", "width", "height") if getattr(args, k) is None]
        if missing:
            raise DancesynthError(f"--openpose needs {', '.join(missing)}; OpenPose files do not store them.")
        clip = importers.import_openpose(args.openpose, args.audio, args.out, args.style, args.fps, args.width,
                                         args.height, clip_id=args.clip_id, split=args.split,
                                         tracker=args.beats)
    else:
        frame = {k: v for k, v in (("fps", args.fps), ("width", args.width), ("height", args.height)) if v is not None}
        clip = importers.import_aistpp(args.aistpp, args.audio, args.out, style=args.style, view=args.view,
                                       clip_id=args.clip_id, split=args.split, tracker=args.beats, **frame)
    logger.info(f"added clip {clip.id} (style {clip.style}, split {clip.split}) to {args.out}")
