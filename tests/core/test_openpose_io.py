"""OpenPose JSON folders: round trip, COCO-18 input, missing people, several people, clear errors."""

import json

import numpy as np
import pytest

from dancesynth.core import openpose_io
from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import NUM_JOINTS, PoseSequence


def random_sequence(frames: int = 5, seed: int = 0) -> PoseSequence:
    rng = np.random.default_rng(seed)
    kp = np.concatenate([rng.uniform(0, 640, (frames, NUM_JOINTS, 1)), rng.uniform(0, 360, (frames, NUM_JOINTS, 1)),
                         rng.uniform(0.1, 1.0, (frames, NUM_JOINTS, 1))], axis=-1)
    return PoseSequence(kp, 15.0, 640, 360)


def write_frame(folder, index: int, people: list[list[float]]) -> None:
    (folder / openpose_io.frame_file_name("video", index)).write_text(
        json.dumps({"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": p} for p in people]}))


def test_round_trip(tmp_path):
    seq = random_sequence()
    seq.keypoints[2] = 0.0  # nobody in frame 2
    folder = openpose_io.save_openpose_folder(seq, tmp_path / "json")
    names = sorted(p.name for p in folder.iterdir())
    assert names[0] == "frame_000000000000_keypoints.json" and len(names) == 5
    assert json.loads((folder / names[2]).read_text())["people"] == []
    back = openpose_io.load_openpose_folder(folder, 15.0, 640, 360)
    assert (back.width, back.height, back.fps) == (640, 360, 15.0)
    np.testing.assert_allclose(back.keypoints, seq.keypoints, atol=1e-3)
    assert [p.name for p in tmp_path.iterdir()] == ["json"]
    openpose_io.save_openpose_folder(random_sequence(3, seed=1), folder)  # replacing an existing folder
    assert len(list(folder.iterdir())) == 3


def test_frames_sorted_by_number_and_coco18(tmp_path):
    coco = np.zeros((18, 3))
    coco[1] = (120, 50, 0.8)   # Neck
    coco[8] = (105, 120, 0.9)  # RHip
    coco[11] = (135, 120, 0.7)  # LHip
    write_frame(tmp_path, 10, [coco.ravel().tolist()])
    write_frame(tmp_path, 9, [])
    (tmp_path / "notes.txt").write_text("ignored")
    seq = openpose_io.load_openpose_folder(tmp_path, 30.0, 200, 200)
    assert len(seq) == 2 and not seq.confidence[0].any()
    assert seq.keypoints[1, 1].tolist() == pytest.approx([120, 50, 0.8])
    assert seq.keypoints[1, 9].tolist() == pytest.approx([105, 120, 0.9])
    assert seq.keypoints[1, 8].tolist() == pytest.approx([120, 120, 0.7])  # MidHip derived from the hips
    assert seq.confidence[1, 19:].sum() == 0  # COCO-18 has no feet


def test_several_people_follow_the_previous_choice(tmp_path):
    def person(x: float, conf: float) -> list[float]:
        kp = np.zeros((NUM_JOINTS, 3))
        kp[:, 0], kp[:, 1], kp[:, 2] = x, 100, conf
        return kp.ravel().tolist()

    write_frame(tmp_path, 0, [person(500, 0.5), person(100, 0.9)])  # most confident first
    write_frame(tmp_path, 1, [person(500, 0.95), person(102, 0.85)])  # someone else is now slightly surer
    seq = openpose_io.load_openpose_folder(tmp_path, 15.0, 640, 360)
    assert seq.keypoints[:, 0, 0].tolist() == [100, 102]


def test_errors(tmp_path):
    with pytest.raises(DancesynthError, match="does not exist"):
        openpose_io.load_openpose_folder(tmp_path / "missing", 15, 640, 360)
    with pytest.raises(DancesynthError, match="no OpenPose"):
        openpose_io.load_openpose_folder(tmp_path, 15, 640, 360)
    (tmp_path / openpose_io.frame_file_name("video", 0)).write_text("{not json")
    with pytest.raises(DancesynthError, match="not a valid OpenPose"):
        openpose_io.load_openpose_folder(tmp_path, 15, 640, 360)
    write_frame(tmp_path, 0, [[1.0, 2.0, 3.0]])
    with pytest.raises(DancesynthError, match="expected 75"):
        openpose_io.load_openpose_folder(tmp_path, 15, 640, 360)
    with pytest.raises(DancesynthError, match="does not exist"):
        openpose_io.save_openpose_folder(random_sequence(), tmp_path / "a" / "b")
