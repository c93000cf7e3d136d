"""What a web job's worker process runs: :func:`run_job` (the spawn target) and one function per job kind.

A worker logs into the job's ``log.txt`` (its stdout and stderr too, so native libraries' messages land there)
with progress lines every :data:`PROGRESS_INTERVAL_S`, and writes ``result.json``: ``{"outputs": {name: path
relative to the data folder}, "info": {...}}`` or ``{"error": sentence}``. SIGTERM (cancel) stops it like Ctrl-C,
so files being written under temporary names are removed; a worker whose server is gone (even killed before the
worker started) stops itself the same way. Heavy modules are imported in the worker only.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from apps.logs import configure_logging, kept_warnings
from apps.web.job_folder import JOB_FILE, LOG_FILE, OUT, RESULT_FILE, write_json
from apps.web.uploads import user_message
from dancesynth.core import progress
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import os_error_sentence

if TYPE_CHECKING:
    from apps.requests import Request

logger = logging.getLogger(__name__)

# Often enough that the page's progress moves while a short dance renders.
PROGRESS_INTERVAL_S = 0.5
PREVIEW_SECONDS = 5.0
# Time an orphaned worker has to clean up as on Ctrl-C before it is ended outright.
ORPHAN_GRACE_S = 5.0
# Files of the demo's folder the page shows (summary.md links to them).
DEMO_FILES = ("summary.md", "frames.png", "dance.mp4", "skeleton.mp4", "side_by_side.mp4", "target/target.mp4",
              "runs/video/losses.png")


def _relative(path: Path, data: Path) -> str:
    return str(Path(path).resolve().relative_to(data.resolve()))


def _request(cls: type[Request], params: dict) -> Request:
    """The request a job keeps as its ``params``; a sentence (not a TypeError) for a job queued by an older
    dancesynth, whose request had other fields."""
    try:
        return cls(**params)
    except TypeError as e:
        raise DancesynthError("This job was queued by an older dancesynth and cannot run; start it again from the "
                              "page.") from e


def dance_job(params: dict, out: Path, settings: dict) -> tuple[dict, dict]:
    """The dance, its skeleton and side-by-side videos, by :func:`apps.pipeline.dance`; ``params`` is the job's
    :class:`~apps.requests.DanceRequest`, its outputs named relative to the job's folder ``out``."""
    from apps.pipeline import dance
    from apps.requests import DanceRequest

    request = _request(DanceRequest, params)
    out.mkdir(exist_ok=True)
    files = {"dance": out / request.out, "skeleton": out / request.skeleton_preview,
             "side_by_side": out / request.side_by_side}
    result = dance(dataclasses.replace(request, out=files["dance"], skeleton_preview=files["skeleton"],
                                       side_by_side=files["side_by_side"]))
    data = Path(settings["data"])
    return ({name: _relative(path, data) for name, path in files.items()},
            {"video_model": str(result.video_model), "frames": len(result.poses), "fps": result.poses.fps})


def train_job(params: dict, out: Path, settings: dict) -> tuple[dict, dict]:
    """Train (or continue) the cached appearance model of a video for ``minutes`` more."""
    from stage2_video.model_cache import appearance_model_for, entry_path, read_entry

    entry = read_entry(entry_path(params["target"], params["preset"], settings["cache"]))
    trained = entry.trained_seconds / 60 if entry is not None else 0.0
    path = appearance_model_for(params["target"], trained + params["minutes"], params["preset"], settings["cache"],
                                settings["device"])
    return {}, {"video_model": str(path)}


def preview_job(params: dict, out: Path, settings: dict) -> tuple[dict, dict]:
    """The tracked person's skeleton over the first :data:`PREVIEW_SECONDS` of the video (mp4), and one frame of
    it (png), so the user sees who will be learnt before training."""
    import cv2

    from dancesynth.core.draw import draw_pose
    from dancesynth.core.fileio import atomic_path, check_outputs
    from dancesynth.core.media import probe_video, read_frames
    from stage2_video.extract import extract_frames, write_preview

    video = Path(params["target"])
    check_outputs({"preview video": out / "preview.mp4", "preview image": out / "preview.png"}, {"video": video})
    info = probe_video(video)
    count = max(1, int(PREVIEW_SECONDS * info.fps))
    frames = list(itertools.islice(read_frames(video), count))
    # The whole path: the job's error message names an upload by the user's name for it (user_message).
    found = extract_frames(frames, info.fps, (info.width, info.height), total=len(frames), source=str(video))
    out.mkdir(exist_ok=True)
    write_preview(video, found.poses, out / "preview.mp4")
    middle = len(frames) // 2
    with atomic_path(out / "preview.png") as tmp:
        image = draw_pose(frames[middle].copy(), found.poses.keypoints[middle])
        cv2.imwrite(str(tmp), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    data = Path(settings["data"])
    return ({"preview": _relative(out / "preview.mp4", data), "image": _relative(out / "preview.png", data)},
            {"found": float(found.found.mean())})


def demo_job(params: dict, out: Path, settings: dict) -> tuple[dict, dict]:
    """:func:`apps.demo.run_demo` of the job's :class:`~apps.requests.DemoRequest` (``params``; its folder is kept
    when cancelled: the demo continues where it stopped), at the sizes of the server's ``DemoPlan``
    (``settings["demo"]``, its fields; None: the default plan)."""
    from apps.demo import DemoPlan, run_demo
    from apps.requests import DemoRequest

    request = _request(DemoRequest, params)
    plan = DemoPlan(**settings["demo"]) if settings.get("demo") else None
    run_demo(**request.api_kwargs(), plan=plan)
    folder, data = Path(request.out), Path(settings["data"])
    return {name: _relative(folder / name, data) for name in DEMO_FILES if (folder / name).is_file()}, {}


TASKS: dict[str, Callable[[dict, Path, dict], tuple[dict, dict]]] = {
    "dance": dance_job, "train": train_job, "preview": preview_job, "demo": demo_job}


def _terminated(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # cancel cleans up (temporary files deleted) exactly like Ctrl-C


def _exit_with_parent() -> None:
    """End this worker (as a cancel would) when the server that started it is gone, even when it went before
    this worker got here: the end of multiprocessing's pipe from the parent closes however the parent ends. A
    worker whose main thread does not reach Python code within :data:`ORPHAN_GRACE_S` (a long native call, an
    import) is ended outright; the next server deletes the job's files as it marks the job interrupted."""
    multiprocessing.parent_process().join()
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(ORPHAN_GRACE_S)
    os._exit(130)


def run_job(job_dir: str, settings: dict) -> None:
    """Run the job in ``job_dir`` (the worker process's entry point)."""
    folder = Path(job_dir)
    signal.signal(signal.SIGTERM, _terminated)
    log = open(folder / LOG_FILE, "a", buffering=1)
    os.dup2(log.fileno(), 1)
    os.dup2(log.fileno(), 2)
    sys.stdout = sys.stderr = log
    configure_logging(logging.INFO, log)
    progress.LOG_INTERVAL_S = PROGRESS_INTERVAL_S
    job = json.loads((folder / JOB_FILE).read_text())
    data = Path(settings["data"])
    with kept_warnings() as warnings:
        try:
            # Watched from here on: a server gone already ends the job at once, as a cancel, with its log line.
            threading.Thread(target=_exit_with_parent, daemon=True).start()
            outputs, info = TASKS[job["kind"]](job["params"], folder / OUT, settings)
            result: dict = {"outputs": outputs, "info": info}
        except KeyboardInterrupt:
            logger.info("cancelled")
            raise SystemExit(130) from None
        except (DancesynthError, OSError) as e:
            message = str(e) if isinstance(e, DancesynthError) else os_error_sentence(e)
            logger.error(message)
            result = {"error": user_message(message, data)}
        except Exception as e:  # noqa: BLE001 - any other failure is reported in the page, its traceback in the log
            traceback.print_exc()
            result = {"error": f"The job failed unexpectedly ({type(e).__name__}: {e}); its log has the details."}
    write_json(folder / RESULT_FILE, {**result, "warnings": [user_message(w, data) for w in warnings]})
