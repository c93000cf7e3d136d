"""Dataset folder layout and manifest: reading, writing and splitting, with no torch dependency.

See :mod:`stage1_pose.data.dataset` for the layout; this module is what generators and importers (and their
worker processes) need to write a dataset folder.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import soundfile

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.media import SONG_SAMPLE_RATE

# Pose frames per second and WAV sample rate (Hz) of the datasets dancesynth writes (built-in and imported): songs
# are stored as every command decodes them, so dataset and user songs give the same features.
POSE_FPS = 15.0
SAMPLE_RATE = SONG_SAMPLE_RATE
MANIFEST = "manifest.json"
FEATURES = "features"
MANIFEST_VERSION = 1
SPLITS: tuple[str, ...] = ("train", "val", "test")
# Fractions of songs in the val and test splits; the rest is train.
HELD_OUT_FRACTION = 0.1
_CLIP_KEYS = ("id", "song", "style", "split", "audio", "poses", "beats")
# Clip ids name files (``features/<kind>/<id>.npy``), so they hold no path separators; importers write only these.
_CLIP_ID = re.compile(r"[A-Za-z0-9_.-]+")


@dataclass(frozen=True)
class Clip:
    """One manifest entry: a song and the dance performed to it (paths relative to the dataset folder)."""

    id: str
    song: str
    style: str
    split: str
    audio: str
    poses: str
    beats: str


def clip_paths(clip_id: str) -> dict[str, str]:
    """The relative ``audio``, ``poses`` and ``beats`` paths of clip ``clip_id`` in the standard layout."""
    return {"audio": f"audio/{clip_id}.wav", "poses": f"poses/{clip_id}.npz", "beats": f"beats/{clip_id}.json"}


def create_layout(root: str | os.PathLike) -> Path:
    """Create ``root`` and its ``audio``, ``poses`` and ``beats`` sub-folders (existing ones are kept)."""
    root = Path(root)
    try:
        for sub in ("audio", "poses", "beats"):
            (root / sub).mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DancesynthError(f"Could not create the dataset folder {root} ({e.strerror or e}); "
                              "check the path and its permissions.") from e
    return root


def write_json(path: str | os.PathLike, data: dict) -> None:
    """Write ``data`` as JSON atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1))


def write_audio(path: str | os.PathLike, samples: np.ndarray, sample_rate: int) -> None:
    """Write mono float ``samples`` as a 16-bit WAV atomically. The WAV is encoded in memory and written by Python,
    because libsndfile reports a full disk or a read-only one only as "System error"."""
    encoded = io.BytesIO()
    soundfile.write(encoded, samples, sample_rate, subtype="PCM_16", format="WAV")
    with atomic_path(path) as tmp:
        tmp.write_bytes(encoded.getvalue())


def write_beats(path: str | os.PathLike, beats: np.ndarray, downbeats: np.ndarray, tempo: float, source: str) -> None:
    """Write a beats file: beat and downbeat times in seconds, tempo in BPM, ``source`` exact or tracked."""
    write_json(path, {"beats": [round(float(b), 6) for b in beats],
                      "downbeats": [round(float(b), 6) for b in downbeats],
                      "tempo": float(tempo), "source": source})


def write_manifest(root: str | os.PathLike, fps: float, sample_rate: int, styles: Sequence[str],
                   clips: Iterable[Clip]) -> Path:
    """Write ``root/manifest.json`` atomically and return its path."""
    path = Path(root) / MANIFEST
    write_json(path, {"version": MANIFEST_VERSION, "fps": float(fps), "sample_rate": int(sample_rate),
                      "styles": list(styles), "clips": [asdict(c) for c in clips]})
    return path


def split_songs(songs_by_style: dict[str, list[str]], rng: np.random.Generator) -> dict[str, str]:
    """Assign every song to ``train``, ``val`` or ``test``, stratified by style.

    Songs are shuffled within each style and dealt round-robin across styles, so the last songs of the deal
    cover every style; the last ``round(10 %)`` go to test and the ``round(10 %)`` before them to val (at
    least one each once there are 3 songs). Returns song -> split.
    """
    shuffled = [list(rng.permutation(songs)) for _, songs in sorted(songs_by_style.items())]
    dealt = [s[i] for i in range(max(map(len, shuffled), default=0)) for s in shuffled if i < len(s)]
    n = len(dealt)
    held = max(1, int(round(n * HELD_OUT_FRACTION))) if n >= 3 else 0
    splits = ["train"] * (n - 2 * held) + ["val"] * held + ["test"] * held
    return {str(song): split for song, split in zip(dealt, splits)}


def split_for_new_song(song: str) -> str:
    """A stable split for a song added after the dataset was made: 80/10/10 by a hash of its id."""
    bucket = int(hashlib.sha1(song.encode()).hexdigest(), 16) % 10
    return "test" if bucket == 9 else "val" if bucket == 8 else "train"


@dataclass(frozen=True)
class Manifest:
    """The contents of ``manifest.json``: pose ``fps``, WAV ``sample_rate`` (Hz), ``styles`` and ``clips``."""

    fps: float
    sample_rate: int
    styles: tuple[str, ...]
    clips: tuple[Clip, ...]


def read_manifest(root: str | os.PathLike) -> Manifest:
    """Read and validate ``root/manifest.json``; a missing folder or file or a malformed manifest raises a
    :class:`DancesynthError` saying how to make one.

    Every clip's files must resolve (symbolic links followed) inside ``root`` and its id must be a plain file
    name, so a downloaded dataset cannot make dancesynth read or write outside its folder.
    """
    root = Path(root)
    path = root / MANIFEST
    if root.exists() and not root.is_dir():
        raise DancesynthError(f"{root} is a file, not a dataset folder; pass the folder made by "
                              "`dancesynth make-dataset --out DIR`.")
    if not root.is_dir():
        raise DancesynthError(f"The dataset folder {root} does not exist; "
                              "create one with `dancesynth make-dataset --out DIR`.")
    if not path.is_file():
        raise DancesynthError(f"{root} has no {MANIFEST}, so it is not a dancesynth dataset; "
                              "create one with `dancesynth make-dataset --out DIR`.")
    try:
        data = json.loads(path.read_text())
        if data["version"] != MANIFEST_VERSION:
            raise DancesynthError(f"{path} has version {data['version']}, but this dancesynth reads version "
                                  f"{MANIFEST_VERSION}; re-create the dataset with `dancesynth make-dataset`.")
        styles = tuple(str(s) for s in data["styles"])
        clips = tuple(Clip(**{k: str(c[k]) for k in _CLIP_KEYS}) for c in data["clips"])
        manifest = Manifest(float(data["fps"]), int(data["sample_rate"]), styles, clips)
    except (ValueError, KeyError, TypeError) as e:
        raise DancesynthError(f"{path} is not a valid dataset manifest ({type(e).__name__}: {e}); "
                              "re-create the dataset with `dancesynth make-dataset`.") from e
    inside = root.resolve()
    if not (inside / FEATURES).resolve().is_relative_to(inside):
        raise DancesynthError(f"{root / FEATURES} links outside the dataset folder; delete that link so the "
                              "feature cache is written inside the dataset.")
    for c in clips:
        if c.split not in SPLITS or c.style not in styles:
            raise DancesynthError(f"Clip {c.id} in {path} has split {c.split!r} / style {c.style!r}, not one of "
                                  f"{SPLITS} / {styles}; fix the manifest or re-create the dataset.")
        if not _CLIP_ID.fullmatch(c.id) or not c.id.strip("."):
            raise DancesynthError(f"Clip id {c.id!r} in {path} is not a plain name (letters, digits and _.- only); "
                                  "fix the manifest or re-create the dataset.")
        for key in ("audio", "poses", "beats"):
            rel = getattr(c, key)
            if Path(rel).is_absolute() or not (inside / rel).resolve().is_relative_to(inside):
                raise DancesynthError(f"Clip {c.id!r} in {path} has its {key} at {rel!r}, outside the dataset folder "
                                      "(links included); a dataset may only use its own files, so fix the manifest "
                                      "or re-create the dataset.")
    return manifest
