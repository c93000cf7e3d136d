"""`dancesynth serve`: the web page for the main job, on this machine."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from apps.arguments import output_folder, positive_float, tcp_port

NAME = "serve"
HELP = "start the web page: upload a song and a video of a person, watch the progress, play and download the dance"
DESCRIPTION = """\
Start a local web app (open the address it prints in a browser) with three tabs:
  Dance              a song (uploaded or built-in) and a person (a cached appearance model, or a video trained
                     now within a minutes budget) -> the dance, its skeleton and side-by-side videos to play and
                     download, with the equivalent `dancesynth dance` command; the pose model is the
                     built-in one or a stage-1 run of --pose-models,
  Appearance models  the cached models with held-out SSIM and training time; train or continue one with a live
                     loss plot and sample image, after a preview of who is tracked in the video,
  Demo               `dancesynth demo` in one click, its summary shown.
Jobs run one at a time in a worker process (the others wait in a queue) and are kept with their outputs in
--data, so a reload or a restart shows them; a job can be cancelled. The page loads nothing from the internet and
sends nothing anywhere; it listens on 127.0.0.1 only unless --host says otherwise (it has no login: do not expose
it to a network you do not trust). It answers requests addressed to --host (or the address a request arrives at;
also localhost on the loopback) and its port only, and changes made from its own page only, so other web sites
cannot use it from your browser. One server uses a --data folder at a time.

examples:
  dancesynth serve
  dancesynth serve --port 8080 --data ~/dances --max-upload-mb 2000
  dancesynth serve --pose-models runs/pose
"""


def _default_data() -> Path:
    """``$XDG_DATA_HOME/dancesynth/web`` (``~/.local/share/dancesynth/web`` when unset)."""
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base) / "dancesynth" / "web"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=tcp_port, default=7860, help="port (default 7860)")
    p.add_argument("--data", type=output_folder, default=None, metavar="DIR",
                   help="folder for uploads, built-in songs, jobs and their outputs "
                        "(default ~/.local/share/dancesynth/web)")
    p.add_argument("--cache", type=output_folder, default=None, metavar="DIR",
                   help="appearance-model cache, shared with `dance --target` (default ~/.cache/dancesynth/appearance)")
    p.add_argument("--pose-models", type=Path, default=None, metavar="DIR",
                   help="folder of stage-1 runs (`dancesynth train-pose --out` folders, in it or one level down) "
                        "offered on the Dance tab besides the built-in pose model")
    p.add_argument("--max-upload-mb", type=positive_float, default=500.0, metavar="MB",
                   help="largest file accepted, in MB (default 500)")
    p.add_argument("--max-song-minutes", type=positive_float, default=10.0, metavar="M",
                   help="longest song accepted, in minutes (default 10)")
    p.add_argument("--keep-uploads-hours", type=positive_float, default=24.0, metavar="H",
                   help="remove uploaded songs and videos older than this many hours, at start and at each upload, "
                        "unless a queued or running job uses them or a cached appearance model was trained on them "
                        "(default 24)")
    p.add_argument("--device", default="auto", help="auto (GPU when available), cpu or cuda (default auto)")


def run(args: argparse.Namespace) -> None:
    from apps.web.server import serve

    serve(args.host, args.port, Path(args.data) if args.data else _default_data(),
          Path(args.cache) if args.cache else None, args.device, args.max_upload_mb, args.max_song_minutes,
          args.pose_models, args.keep_uploads_hours)
