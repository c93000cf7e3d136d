"""Read and write OpenPose's per-frame JSON keypoint folders (BODY_25, or COCO-18 on reading)."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.skeleton import COCO18_TO_BODY25, NUM_JOINTS, PoseSequence, from_partial

_FRAME_NUMBER = re.compile(r"_(\d+)_keypoints\.json$")
_COCO18_VALUES = 18 * 3
_BODY25_VALUES = NUM_JOINTS * 3


def frame_file_name(prefix: str, index: int) -> str:
    """OpenPose's name for frame ``index``: ``<prefix>_<12-digit index>_keypoints.json``."""
    return f"{prefix}_{index:012d}_keypoints.json"


def save_openpose_folder(seq: PoseSequence, folder: str | os.PathLike, prefix: str = "frame") -> Path:
    """Write one OpenPose JSON file per frame into ``folder`` (created; replaced if it exists), atomically.

    A frame whose joints are all absent (confidence 0) is written with an empty ``people`` list, as OpenPose
    does when it sees nobody. The files are written into a temporary sibling folder that is renamed when complete.
    """
    folder = Path(folder)
    with atomic_path(folder, folder=True) as tmp:
        tmp.mkdir()
        for i, kp in enumerate(seq.keypoints):
            people = []
            if (kp[:, 2] > 0).any():
                values = [round(float(v), 3) for v in kp.reshape(-1)]
                people.append({"person_id": [-1], "pose_keypoints_2d": values, "face_keypoints_2d": [],
                               "hand_left_keypoints_2d": [], "hand_right_keypoints_2d": []})
            (tmp / frame_file_name(prefix, i)).write_text(json.dumps({"version": 1.3, "people": people}))
    return folder


def _read_people(path: Path) -> list[np.ndarray]:
    """The people in one OpenPose JSON file, each as ``[25, 3]`` BODY_25 (COCO-18 is mapped)."""
    try:
        data = json.loads(path.read_text())
        people = data["people"]
        if not isinstance(people, list):
            raise TypeError("people is not a list")
        out = []
        for person in people:
            values = np.asarray(person["pose_keypoints_2d"], dtype=np.float32)
            if values.size == _BODY25_VALUES:
                out.append(values.reshape(NUM_JOINTS, 3))
            elif values.size == _COCO18_VALUES:
                out.append(from_partial(values.reshape(1, 18, 3), COCO18_TO_BODY25, 1.0, 1, 1).keypoints[0])
            elif values.size:
                raise ValueError(f"{values.size} pose values (expected 75 for BODY_25 or 54 for COCO-18)")
    except (OSError, ValueError, TypeError, KeyError) as e:
        raise DancesynthError(f"{path} is not a valid OpenPose keypoint file ({e}); re-run OpenPose with "
                              "--write_json and the BODY_25 or COCO model.") from e
    return out


def _choose(people: list[np.ndarray], previous: np.ndarray | None, scale: float) -> np.ndarray:
    """The person with the highest total confidence, discounted by distance from the previous frame's choice.

    The distance (mean over joints present in both, in units of ``scale`` pixels) is subtracted from the
    total confidence, so a slightly less certain detection at the same place wins over a jump to someone else.
    """
    if len(people) == 1 or previous is None:
        return max(people, key=lambda p: float(p[:, 2].sum()))

    def score(p: np.ndarray) -> float:
        both = (p[:, 2] > 0) & (previous[:, 2] > 0)
        jump = float(np.linalg.norm(p[both, :2] - previous[both, :2], axis=1).mean()) / scale if both.any() else 0.0
        return float(p[:, 2].sum()) - NUM_JOINTS * jump

    return max(people, key=score)


def load_openpose_folder(folder: str | os.PathLike, fps: float, width: int, height: int) -> PoseSequence:
    """Read a folder of OpenPose ``*_keypoints.json`` files into a PoseSequence (one frame per file).

    Files are ordered by the frame number in their name. A frame with nobody gets all confidences 0; with
    several people the one with the highest total confidence close to the previous frame's choice is kept
    (see :func:`_choose`). COCO-18 output is mapped to BODY_25 (Neck/MidHip derived, feet absent).

    Args:
        fps: the video's frame rate; width, height: the video's size in pixels (OpenPose does not store them).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DancesynthError(f"The OpenPose folder {folder} does not exist; check the path.")
    files = [(int(m.group(1)), p) for p in folder.iterdir() if (m := _FRAME_NUMBER.search(p.name))]
    if not files:
        raise DancesynthError(f"{folder} contains no OpenPose *_keypoints.json files; run OpenPose with "
                              "--write_json on your video first.")
    files.sort()
    scale = max(width, height) / 10.0  # a body-sized distance, so jumps are judged relative to the frame
    frames, previous = [], None
    for _, path in files:
        people = _read_people(path)
        if people:
            previous = _choose(people, previous, scale)
            frames.append(previous)
        else:
            frames.append(np.zeros((NUM_JOINTS, 3), np.float32))
    return PoseSequence(np.stack(frames), fps, width, height)
