"""`dancesynth render`: pose sequence -> video of the target person."""

from __future__ import annotations

import argparse
import logging

from apps.requests import RenderRequest

NAME = RenderRequest.COMMAND
HELP = "render a pose sequence as a video of the person a train-video model learned"
DESCRIPTION = """\
Render POSES (a dancesynth .npz pose file, e.g. from `dancesynth generate` or `dancesynth extract-poses`) with
an appearance model trained by `dancesynth train-video`, through the frame pipeline of `dancesynth dance`: the
poses are resampled to the target video's frame rate, given the target person's own bone lengths, then
normalised onto their body (Everybody Dance Now: scale and position from ankle heights and body size;
--no-normalize skips both, for poses already on the target's canvas), rendered and composited into the target's
scene. The output mp4 has the target video's resolution (or --height; --crop writes the model's crop) and frame
rate; --audio muxes a song (cut to the video's length).

examples:
  dancesynth render dance.npz --model runs/person --out dance.mp4 --audio song.mp3
  dancesynth render dance.npz --model runs/person --out crop.mp4 --crop --side-by-side compare.mp4
  dancesynth render runs/person/poses.npz --model runs/person --out replay.mp4 --no-normalize
"""

logger = logging.getLogger(__name__)


add_arguments = RenderRequest.add_arguments


def run(args: argparse.Namespace) -> None:
    import torch

    request = RenderRequest.from_namespace(args)
    if request.threads:
        torch.set_num_threads(request.threads)
    from dancesynth.api import render

    result = render(**request.api_kwargs())
    logger.info(f"{len(result.poses)} frames at {result.poses.fps:g} fps; wrote "
                + ", ".join(map(str, result.written)))
