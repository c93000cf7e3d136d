"""`dancesynth extract-poses`: video of a person -> BODY_25 pose file (+ optional overlay preview)."""

from __future__ import annotations

import argparse
import logging

from apps.requests import ExtractPosesRequest

NAME = ExtractPosesRequest.COMMAND
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


add_arguments = ExtractPosesRequest.add_arguments


def run(args: argparse.Namespace) -> None:
    from dancesynth.api import extract_poses

    result = extract_poses(**ExtractPosesRequest.from_namespace(args).api_kwargs())
    poses, stats = result.poses, result.stats
    logger.info(f"Wrote {args.out}: {len(poses)} frames at {poses.fps:g} fps, {poses.width}x{poses.height} px; "
                f"person found in {result.found.mean():.0%} of frames ({stats.jumps_rejected} jumps to another "
                f"person rejected, {stats.reacquired} re-acquisitions, {stats.missing} frames interpolated).")
    if args.preview is not None:
        logger.info(f"Wrote {args.preview}: the skeleton over the video.")
