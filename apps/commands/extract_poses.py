"""`dancesynth extract-poses`: video of a person -> BODY_25 pose file (+ optional overlay preview)."""

from __future__ import annotations

import argparse
import logging

from apps.arguments import existing_file, fraction, non_negative_float, output_file, positive_float

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

logger = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("video", type=existing_file, help="input video (any resolution; phone rotation is honoured)")
    parser.add_argument("--out", type=output_file, required=True, metavar="POSES.npz", help="output pose file (.npz)")
    parser.add_argument("--preview", type=output_file, metavar="OVERLAY.mp4",
                        help="also write this mp4: the skeleton drawn over the video")
    # Defaults live in stage2_video.extract.ExtractConfig; None here means "use it" (keeps --help fast).
    parser.add_argument("--smoothing", default="savgol",
                        help="temporal filter: savgol (no lag, default), one-euro (causal) or none")
    parser.add_argument("--window", type=positive_float, metavar="SECONDS",
                        help="savgol window length in seconds (default 0.2)")
    parser.add_argument("--min-cutoff", type=positive_float, metavar="HZ",
                        help="one-euro cut-off at rest in Hz, lower = smoother (default 1.0)")
    parser.add_argument("--beta", type=non_negative_float, metavar="B",
                        help="one-euro speed coefficient, higher = less lag on fast moves (default 20)")
    parser.add_argument("--min-visibility", type=fraction, metavar="V",
                        help="BlazePose visibility below which a joint counts as absent (default 0.5)")
    parser.add_argument("--max-missing", type=fraction, metavar="FRACTION",
                        help="fail when the person is missing in more than this fraction of frames (default 0.5)")


def run(args: argparse.Namespace) -> None:
    from dancesynth.api import extract_poses

    result = extract_poses(args.video, out=args.out, preview=args.preview, smoothing=args.smoothing,
                           window_s=args.window, min_cutoff_hz=args.min_cutoff, beta=args.beta,
                           min_visibility=args.min_visibility, max_missing=args.max_missing)
    poses, stats = result.poses, result.stats
    logger.info(f"Wrote {args.out}: {len(poses)} frames at {poses.fps:g} fps, {poses.width}x{poses.height} px; "
                f"person found in {result.found.mean():.0%} of frames ({stats.jumps_rejected} jumps to another "
                f"person rejected, {stats.reacquired} re-acquisitions, {stats.missing} frames interpolated).")
    if args.preview is not None:
        logger.info(f"Wrote {args.preview}: the skeleton over the video.")
