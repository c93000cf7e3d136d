"""`dancesynth dance`: song + trained pose and video models -> dancing video with the song's audio."""

from __future__ import annotations

import argparse
import logging

from apps.requests import DanceRequest

NAME = DanceRequest.COMMAND
HELP = "make a video of the target person dancing to a song"
DESCRIPTION = """\
Generate a dance for SONG with a stage-1 pose model (the one shipped with dancesynth unless --pose-model is
given), resample it to the target video's frame rate, move it onto the target person's body (the person's own
bone lengths, then Everybody-Dance-Now normalisation) and render it with their appearance model, composited into
their own scene: the frame pipeline `dancesynth render` runs on a pose file. The output mp4 has the target
video's resolution (or --height) and frame rate and the song segment as AAC audio; picture and sound last the
segment's duration within one frame.

The person comes from --target VIDEO (one command: their appearance model is looked up in the cache, keyed by
the video's content and the preset, or trained now for --train-minutes; a later call with more minutes continues
it; a call with the same video and no more minutes starts rendering at once) or from --video-model RUN (a
run folder of `dancesynth train-video`).

SONG may be any audio FFmpeg reads (wav, mp3, ogg, m4a, flac, or the soundtrack of a video).

examples:
  dancesynth dance song.mp3 --target me.mp4 --out me_dancing.mp4
  dancesynth dance song.mp3 --target me.mp4 --train-minutes 60 --start 30 --duration 20 --out me.mp4
  dancesynth dance song.mp3 --video-model runs/me --pose-model runs/pose/dance_revolution \\
      --out me_dancing.mp4 --side-by-side compare.mp4
"""

logger = logging.getLogger(__name__)


add_arguments = DanceRequest.add_arguments


def run(args: argparse.Namespace) -> None:
    from dancesynth.api import dance

    result = dance(**DanceRequest.from_namespace(args).api_kwargs())
    logger.info(f"{len(result.poses)} frames at {result.poses.fps:g} fps with the appearance model "
                f"{result.video_model}; wrote " + ", ".join(map(str, result.written)))
