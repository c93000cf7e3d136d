"""Add real recordings to a dataset folder: OpenPose JSON folders and AIST++ 2D keypoints, each with its song.

Both importers resample the dance to the dataset layout's ``POSE_FPS`` (15 fps), decode the song to its
``SAMPLE_RATE`` (22050 Hz) mono, trim both to their common length, track the song's beats and downbeats
(source ``tracked``; tracker ``combined``, ``learned`` or ``dsp``: :func:`stage1_pose.beats.song_beats`) and
append one clip to the manifest, creating the dataset folder when it does not exist. A song is identified by a hash
of its samples, so several dances to one song share its split.

AIST++ publishes its 2D keypoints as Python pickles, which this project never unpickles (a pickle can run
code). Convert each file once, in a Python session you trust, to a NumPy array::

    import pickle, numpy as np
    with open("gBR_sBM_cAll_d04_mBR0_ch01.pkl", "rb") as f:
        np.save("gBR_sBM_cAll_d04_mBR0_ch01.npy", pickle.load(f)["keypoints2d"])  # [9 views, T, 17, 3]

and import the ``.npy`` with its music file (``mBR0.mp3`` for the example above).
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import require_file
from dancesynth.core.skeleton import COCO17_TO_BODY25, PoseSequence, from_partial, resample
from stage1_pose.beats import DEFAULT_BEAT_TRACKER, song_beats
from stage1_pose.data.layout import (
    MANIFEST,
    POSE_FPS,
    SAMPLE_RATE,
    SPLITS,
    Clip,
    clip_paths,
    create_layout,
    read_manifest,
    split_for_new_song,
    write_audio,
    write_beats,
    write_manifest,
)
from stage1_pose.music_features import num_pose_frames

# AIST++ genre codes (the "g.." part of a sequence name) and the dance genres they stand for.
AIST_GENRES = {"gBR": "break", "gPO": "pop", "gLO": "lock", "gMH": "middle_hiphop", "gLH": "la_hiphop",
               "gHO": "house", "gWA": "waack", "gKR": "krump", "gJS": "street_jazz", "gJB": "ballet_jazz"}
AIST_FPS, AIST_WIDTH, AIST_HEIGHT = 60.0, 1920, 1080
_ID_CHARS = re.compile(r"[^A-Za-z0-9_.-]+")


def add_clip(out_dir: str | os.PathLike, poses: PoseSequence, song_path: str | os.PathLike, style: str,
             clip_id: str, split: str | None = None, tracker: str = DEFAULT_BEAT_TRACKER) -> Clip:
    """Append a (dance, song file) pair to the dataset folder ``out_dir`` (created if needed) and return its clip.

    Args:
        poses: the dance, at any fps (resampled to the dataset's).
        song_path: any audio file FFmpeg reads; silent or very short songs are rejected.
        style: style label (added to the dataset's styles when new).
        clip_id: the new clip's id (letters, digits, ``_.-``); must not be in the dataset yet.
        split: ``train``, ``val`` or ``test``; default: the split of this song's other clips, or a stable
            80/10/10 choice by song.
        tracker: the beat tracker, ``combined``, ``learned`` or ``dsp`` (:data:`stage1_pose.beats.BEAT_TRACKERS`).
    """
    from dancesynth.core.media import load_song

    _check_split(split)
    return add_clip_samples(out_dir, poses, load_song(song_path, SAMPLE_RATE), style, clip_id, split,
                            tracker=tracker)


def add_clip_samples(out_dir: str | os.PathLike, poses: PoseSequence, samples: np.ndarray, style: str,
                     clip_id: str, split: str | None = None, song: str | None = None,
                     tracker: str = DEFAULT_BEAT_TRACKER) -> Clip:
    """:func:`add_clip` for a song already decoded: mono ``[N]`` float samples at the dataset's 22050 Hz.

    Args:
        song: the song's id (clips with one id share a split); default: a hash of ``samples``.
    """
    root = Path(out_dir)
    clip_id = _ID_CHARS.sub("_", clip_id)
    _check_split(split)
    if (root / MANIFEST).exists():
        manifest = read_manifest(root)
        if manifest.fps != POSE_FPS or manifest.sample_rate != SAMPLE_RATE:
            raise DancesynthError(f"{root} stores {manifest.fps:g} fps / {manifest.sample_rate} Hz clips, but "
                                  f"importers write {POSE_FPS:g} fps / {SAMPLE_RATE} Hz; import into a new folder.")
        styles, clips = list(manifest.styles), list(manifest.clips)
    else:
        create_layout(root)
        styles, clips = [], []
    if any(c.id == clip_id for c in clips):
        raise DancesynthError(f"{root} already has a clip {clip_id!r}; choose another clip id.")
    poses = resample(poses, POSE_FPS) if poses.fps != POSE_FPS else poses
    frames = min(len(poses), num_pose_frames(len(samples), SAMPLE_RATE, POSE_FPS))
    if frames < POSE_FPS:
        raise DancesynthError(f"The dance {clip_id!r} and its song overlap for less than a second; "
                              "check that they belong together.")
    poses = poses.slice_frames(0, frames)
    samples = samples[:int(round(frames / POSE_FPS * SAMPLE_RATE))]
    song = song or song_id(samples)
    same_song = [c.split for c in clips if c.song == song]
    split = split or (same_song[0] if same_song else split_for_new_song(song))
    paths = clip_paths(clip_id)
    write_audio(root / paths["audio"], samples, SAMPLE_RATE)
    poses.save(root / paths["poses"])
    tracked = song_beats(samples, SAMPLE_RATE, tracker)
    write_beats(root / paths["beats"], tracked.beats, tracked.downbeats, tracked.bpm, "tracked")
    clip = Clip(id=clip_id, song=song, style=style, split=split, **paths)
    write_manifest(root, POSE_FPS, SAMPLE_RATE, styles + ([style] if style not in styles else []), clips + [clip])
    return clip


def _check_split(split: str | None) -> None:
    if split is not None and split not in SPLITS:
        raise DancesynthError(f"Unknown split {split!r}; choose one of {', '.join(SPLITS)}.")


def song_id(samples: np.ndarray) -> str:
    """A song's id in a dataset: a hash of its samples."""
    return "song_" + hashlib.sha1(np.ascontiguousarray(samples, np.float32).tobytes()).hexdigest()[:12]


def import_openpose(json_folder: str | os.PathLike, audio_path: str | os.PathLike, out_dir: str | os.PathLike,
                    style: str, fps: float, width: int, height: int, clip_id: str | None = None,
                    split: str | None = None, tracker: str = DEFAULT_BEAT_TRACKER) -> Clip:
    """Import an OpenPose ``*_keypoints.json`` folder (one file per video frame, BODY_25 or COCO-18) and the
    song of that video into the dataset folder ``out_dir``.

    Args:
        fps, width, height: the video's frame rate and size in pixels (OpenPose does not store them).
        clip_id: default: the folder's name. See :func:`add_clip` for the rest.
    """
    from dancesynth.core.openpose_io import load_openpose_folder

    poses = load_openpose_folder(json_folder, fps, width, height)
    return add_clip(out_dir, poses, audio_path, style, clip_id or Path(json_folder).name, split, tracker)


def load_aistpp_keypoints(path: str | os.PathLike, view: int = 0) -> np.ndarray:
    """``[T, 17, 3]`` float32 COCO-17 (x, y pixels, confidence) from a converted AIST++ keypoints2d file.

    Accepts ``.npy`` or ``.npz`` (key ``keypoints2d``, or its only array) holding ``[views, T, 17, 3]`` (camera
    ``view`` is taken) or ``[T, 17, 3]``. NaN points (not detected) get confidence 0.
    """
    path = require_file(path)
    if path.suffix == ".pkl":
        raise DancesynthError(f"{path} is a pickle, which dancesynth does not open; convert it to .npy as "
                              "described in `stage1_pose.data.importers` (one line of Python) and import that.")
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as e:
        raise DancesynthError(f"{path} is not a NumPy .npy/.npz array ({e}); convert it as described in "
                              "`stage1_pose.data.importers`.") from e
    if isinstance(loaded, np.lib.npyio.NpzFile):
        with loaded:
            keys = list(loaded.keys())
            key = "keypoints2d" if "keypoints2d" in keys else keys[0] if len(keys) == 1 else None
            if key is None:
                raise DancesynthError(f"{path} holds arrays {keys} but none named keypoints2d; save the keypoints "
                                      "under that name.")
            loaded = loaded[key]
    points = np.asarray(loaded, np.float32)
    if points.ndim == 4:
        if not 0 <= view < points.shape[0]:
            raise DancesynthError(f"{path} has {points.shape[0]} camera views; choose a view from 0 to "
                                  f"{points.shape[0] - 1}.")
        points = points[view]
    if points.ndim != 3 or points.shape[1:] != (17, 3) or len(points) == 0:
        raise DancesynthError(f"{path} has shape {points.shape}, not [views, T, 17, 3] or [T, 17, 3] COCO-17 "
                              "keypoints; check that it is an AIST++ keypoints2d array.")
    missing = ~np.isfinite(points).all(axis=-1)
    points = np.nan_to_num(points)
    points[missing] = 0.0
    return points


def import_aistpp(keypoints2d_file: str | os.PathLike, audio_path: str | os.PathLike, out_dir: str | os.PathLike,
                  style: str | None = None, view: int = 0, fps: float = AIST_FPS, width: int = AIST_WIDTH,
                  height: int = AIST_HEIGHT, clip_id: str | None = None, split: str | None = None,
                  tracker: str = DEFAULT_BEAT_TRACKER) -> Clip:
    """Import one AIST++ sequence: converted 2D keypoints (see the module docstring; COCO-17 at 60 fps on
    1920x1080 by default) and its music file, mapped to BODY_25 and resampled to 15 fps.

    Args:
        style: default: the genre in the sequence name (``gBR_...`` -> ``break``, see :data:`AIST_GENRES`).
        view: which camera of a multi-view array.
        clip_id: default: the file name without extension. See :func:`add_clip` for the rest.
    """
    name = Path(keypoints2d_file).stem
    if style is None:
        code = name.split("_")[0]
        if code not in AIST_GENRES:
            raise DancesynthError(f"Cannot tell the genre of {name!r} (AIST++ names start with a genre code such as "
                                  "gBR_); pass the style explicitly.")
        style = AIST_GENRES[code]
    points = load_aistpp_keypoints(keypoints2d_file, view)
    poses = from_partial(points, COCO17_TO_BODY25, fps, width, height)
    return add_clip(out_dir, poses, audio_path, style, clip_id or name, split, tracker)
