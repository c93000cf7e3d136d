"""`dancesynth extract-poses`: video of a person -> BODY_25 pose file (+ optional overlay preview)."""

from __future__ import annotations

import argparse
from pathlib import Path

from dancesynth.core.errors import DancesynthError
from stage2_video.extract import ExtractConfig, extract_poses, write_preview
from stage2_video.smoothing import METHODS, SmoothingConfig

NAME = "extract-poses"
HELP = "extract one person's BODY_25 skeleton from every frame of a video"
DESCRIPTION = """\
Find one person in a video and write their 2D BODY_25 skeleton for every frame.

Uses the BlazePose model bundled with mediapipe (runs on the CPU, no download). When several people are
visible, the largest one near the centre of the first frame where anybody is found is followed; jumps of the
pose estimator to somebody else are detected and undone. Frames where the person is lost get their joints
interpolated in time, then a light temporal filter removes jitter.

Output (.npz, read with dancesynth.core.skeleton.PoseSequence.load): keypoints [frames, 25, 3] float32 =
x, y in pixels of the upright video frame and confidence (BlazePose visibility; 0 = joint absent; small toes
are always absent), fps, width, height, layout="BODY_25".

examples:
  dancesynth extract-poses me.mp4 --out me_poses.npz
  dancesynth extract-poses me.mp4 --out me_poses.npz --preview me_overlay.mp4 --smoothing one-euro
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("video", type=Path, help="input video (any resolution; phone rotation is honoured)")
    parser.add_argument("--out", type=Path, required=True, metavar="POSES.npz", help="output pose file (.npz)")
    parser.add_argument("--preview", type=Path, metavar="OVERLAY.mp4",
                        help="also write this mp4: the skeleton drawn over the video")
    parser.add_argument("--smoothing", choices=METHODS, default="savgol",
                        help="temporal filter: savgol (no lag, default), one-euro (causal) or none")
    parser.add_argument("--window", type=float, default=SmoothingConfig.window_s, metavar="SECONDS",
                        help="savgol window length in seconds (default %(default)s)")
    parser.add_argument("--min-cutoff", type=float, default=SmoothingConfig.min_cutoff_hz, metavar="HZ",
                        help="one-euro cut-off at rest in Hz, lower = smoother (default %(default)s)")
    parser.add_argument("--beta", type=float, default=SmoothingConfig.beta, metavar="B",
                        help="one-euro speed coefficient, higher = less lag on fast moves (default %(default)s)")
    parser.add_argument("--min-visibility", type=float, default=ExtractConfig.min_visibility, metavar="V",
                        help="BlazePose visibility below which a joint counts as absent (default %(default)s)")
    parser.add_argument("--max-missing", type=float, default=ExtractConfig.max_missing_fraction,
                        metavar="FRACTION",
                        help="fail when the person is missing in more than this fraction of frames "
                             "(default %(default)s)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> None:
    if args.out.suffix != ".npz":
        raise DancesynthError(f"--out {args.out} must end in .npz; pose files are numpy .npz archives.")
    if args.preview is not None and args.preview.suffix != ".mp4":
        raise DancesynthError(f"--preview {args.preview} must end in .mp4.")
    for path in (args.out, args.preview):
        if path is not None and not path.parent.is_dir():
            raise DancesynthError(f"The folder {path.parent} does not exist; create it or choose another path.")
    config = ExtractConfig(
        min_visibility=args.min_visibility,
        max_missing_fraction=args.max_missing,
        smoothing=SmoothingConfig(args.smoothing, window_s=args.window, min_cutoff_hz=args.min_cutoff,
                                  beta=args.beta),
    )
    result = extract_poses(args.video, config, progress=not args.quiet)
    poses, stats = result.poses, result.stats
    poses.save(args.out)
    print(f"Wrote {args.out}: {len(poses)} frames at {poses.fps:g} fps, {poses.width}x{poses.height} px; "
          f"person found in {result.found.mean():.0%} of frames ({stats.jumps_rejected} jumps to another "
          f"person rejected, {stats.reacquired} re-acquisitions, {stats.missing} frames interpolated).")
    if args.preview is not None:
        write_preview(args.video, poses, args.preview, progress=not args.quiet)
        print(f"Wrote {args.preview}: the skeleton over the video.")
