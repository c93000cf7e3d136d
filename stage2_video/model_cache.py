"""The appearance-model cache behind `dance --target VIDEO`: one trained model per (video content, preset).

An entry is an ordinary stage-2 run folder (:mod:`stage2_video.train`) named ``<sha256 prefix>-<preset>``
under the cache folder, plus ``source.json`` (the video's full SHA-256, its path when first seen, the preset).
Looking a video up trains only what is missing: no entry -> train for ``minutes``; an entry trained for fewer
minutes (or interrupted) -> resume it for the difference; an entry trained for ``minutes`` or more (or to its
last epoch) -> used as it is. The key is the file's content, so a renamed copy finds its model and an edited
video gets a new one. A lock file keeps two processes from training one entry at once; a run folder's
checkpoints are atomic, so an interrupted training leaves the entry at its last checkpoint, resumable.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from dancesynth.core.checkpoint import POINTER, has_checkpoint, load_meta, run_file_contents
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path, require_file
from dancesynth.core.media import probe_video
from stage2_video.train import KIND, TrainOptions, train_video
from stage2_video.training_data import video_digest

SOURCE_FILE = "source.json"
LOCK_FILE = ".lock"
# Shorter targets hold too few distinct poses to learn a person from (and too few frames to hold out).
MIN_TARGET_SECONDS = 3.0
# A budget is met when the trained time is within this of it (rounding; a run stops at the first step past its
# deadline, so a finished call has trained at least its budget).
BUDGET_SLACK_S = 1.0


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/dancesynth/appearance`` (``~/.cache/dancesynth/appearance`` when unset)."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "dancesynth" / "appearance"


@dataclass(frozen=True)
class CacheEntry:
    """One cached appearance model: its run folder and how long it has trained (seconds, all calls)."""

    path: Path
    video_sha256: str
    preset: str
    trained_seconds: float
    finished: bool  # trained to its last epoch: more minutes add nothing


def entry_path(video: str | os.PathLike, preset: str, cache: str | os.PathLike | None = None) -> Path:
    """The run folder that holds (or will hold) the model of ``video`` at ``preset``."""
    return Path(cache or default_cache_dir()) / f"{video_digest(Path(video))[:24]}-{preset}"


def read_entry(path: Path) -> CacheEntry | None:
    """The entry at ``path``, or None when it holds no checkpoint yet."""
    if not has_checkpoint(path):
        return None
    meta = load_meta(path, KIND)
    with run_file_contents(path / SOURCE_FILE):
        source = json.loads((path / SOURCE_FILE).read_text()) if (path / SOURCE_FILE).is_file() else {}
    if not isinstance(source, dict):
        raise DancesynthError(f"{path / SOURCE_FILE} holds a JSON {type(source).__name__}, not an object; it was "
                              f"edited or damaged, so delete the folder {path} and its model is trained again.")
    with run_file_contents(path / POINTER):
        return CacheEntry(path, source.get("video_sha256", ""), source.get("preset", ""),
                          float(meta.get("trained_seconds", 0.0)), int(meta["epoch"]) >= int(meta["total_epochs"]))


def list_entries(cache: str | os.PathLike | None = None) -> list[CacheEntry]:
    """Every trained entry in the cache folder, newest first."""
    root = Path(cache or default_cache_dir())
    entries = [read_entry(p) for p in root.iterdir() if p.is_dir()] if root.is_dir() else []
    return sorted((e for e in entries if e is not None), key=lambda e: -(e.path / "latest.json").stat().st_mtime)


def _done(entry: CacheEntry | None, minutes: float) -> bool:
    return entry is not None and (entry.finished or entry.trained_seconds >= 60 * minutes - BUDGET_SLACK_S)


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Hold the entry's lock; another process holding it is a user error (one training per entry)."""
    path.mkdir(parents=True, exist_ok=True)
    with open(path / LOCK_FILE, "w") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError as e:
            raise DancesynthError(f"Another dancesynth process is training the appearance model in {path}; "
                                  "wait for it to finish and try again.") from e
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def check_target_video(video: Path) -> None:
    """Refuse a target that cannot hold enough of a person: missing, unreadable or shorter than 3 s."""
    require_file(video, "Target video")
    info = probe_video(video)
    if info.duration < MIN_TARGET_SECONDS:
        raise DancesynthError(f"The target video {video} lasts {info.duration:.1f} s; use one of at least "
                              f"{MIN_TARGET_SECONDS:g} s that shows the person moving.")


def train_for(video: str | os.PathLike, run_dir: str | os.PathLike, minutes: float, preset: str = "small",
              device: str = "auto", precision: str = "auto", poses: str | os.PathLike | None = None) -> None:
    """Train the run ``run_dir`` until it has trained ``minutes`` in all (every call together): start it, resume
    it for the minutes it lacks (e.g. after an interruption), or leave it when done or trained to its last epoch.
    ``poses``: a pose file of ``video`` to use instead of extracting (see :func:`train_video`)."""
    entry = read_entry(Path(run_dir))
    if _done(entry, minutes):
        return
    train_video(video, run_dir, preset, TrainOptions(minutes=minutes), resume=entry is not None, poses=poses,
                device=device, precision=precision)


def appearance_model_for(video: str | os.PathLike, minutes: float, preset: str = "small",
                         cache: str | os.PathLike | None = None, device: str = "auto",
                         precision: str = "auto") -> Path:
    """The run folder of a model of the person in ``video`` trained for at least ``minutes`` (all calls
    together): found in the cache, trained now, or resumed for the minutes it lacks."""
    video = Path(video)
    check_target_video(video)
    path = entry_path(video, preset, cache)
    if _done(read_entry(path), minutes):
        return path
    # Another process may train it in the meantime: the lock waits for nobody, and train_for looks again.
    created = not path.exists()
    with _locked(path):
        try:
            if not (path / SOURCE_FILE).is_file():
                with atomic_path(path / SOURCE_FILE) as tmp:
                    tmp.write_text(json.dumps({"video_sha256": video_digest(video), "video": str(video.resolve()),
                                               "preset": preset}, indent=2))
            train_for(video, path, minutes, preset, device, precision)
        except BaseException:
            # A failure before the first checkpoint (e.g. no person in the video) leaves no half-made entry;
            # the lock is still held, so no other process is using the folder.
            if created and not has_checkpoint(path):
                shutil.rmtree(path, ignore_errors=True)
            raise
    return path
