"""`dancesynth extract-poses` end to end on a short video made from a real photo."""

import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import skimage.data

from apps.cli import main
from dancesynth.core.media import probe_video, write_video
from dancesynth.core.skeleton import JOINT_INDEX, PoseSequence

NAME = "extract-poses"
# What mediapipe's native code writes to stderr: absl lines (W0000 12:34:56.789 ... file.cc:114]) and TF Lite's.
NATIVE = re.compile(r"^[IWEF]\d{4} |\.cc:\d+\]|TensorFlow Lite|absl::", re.MULTILINE)


def _person_moving_right(count: int, step: int) -> list[np.ndarray]:
    """``count`` 240x200 frames of a photographed person shifted ``step`` pixels right per frame."""
    person = cv2.resize(skimage.data.astronaut(), (160, 160), interpolation=cv2.INTER_AREA)
    frames = []
    for t in range(count):
        frame = np.full((200, 240, 3), 60, np.uint8)
        frame[20:180, 10 + step * t:170 + step * t] = person
        frames.append(frame)
    return frames


def test_extract_poses_writes_poses_and_preview(tmp_path, capsys):
    frames = _person_moving_right(5, 10)
    video, out, preview = tmp_path / "clip.mp4", tmp_path / "poses.npz", tmp_path / "overlay.mp4"
    write_video(video, frames, 12)
    assert main([NAME, str(video), "--out", str(out), "--preview", str(preview)]) == 0
    poses = PoseSequence.load(out)
    assert (len(poses), poses.fps, poses.width, poses.height) == (5, 12, 240, 200)
    nose_x = poses.keypoints[:, JOINT_INDEX["Nose"], 0]
    assert np.all(np.diff(nose_x) > 5)
    info = probe_video(preview)
    assert (info.num_frames, info.width, info.height) == (5, 240, 200)
    assert "person found in 100% of frames" in capsys.readouterr().err


def test_extract_poses_reports_user_errors_without_traceback(tmp_path, capsys):
    assert main([NAME, str(tmp_path / "missing.mp4"), "--out", str(tmp_path / "p.npz")]) == 1
    assert "missing.mp4 does not exist" in capsys.readouterr().err
    video = tmp_path / "v.mp4"
    video.write_bytes(b"never decoded")
    assert main([NAME, str(video), "--out", str(tmp_path / "p.json")]) == 1
    assert "must end in .npz" in capsys.readouterr().err
    assert main([NAME, str(video), "--out", str(tmp_path / "p.npz"), "--smoothing", "savgol", "--window", "-1"]) == 1
    assert "must be positive" in capsys.readouterr().err


def test_quiet_shows_only_warnings_not_mediapipe_log_lines(tmp_path, truncated_video):
    """mediapipe's native absl / TF Lite lines ignore every setting; -q hides them, but not dancesynth's warnings."""
    video = truncated_video(_person_moving_right(16, 2), tmp_path / "cut.mp4", fps=12)
    done = subprocess.run([sys.executable, "-m", "apps.cli", NAME, "-q", str(video), "--out", str(tmp_path / "p.npz")],
                          capture_output=True, text=True, cwd=Path(__file__).parents[2], timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"warning: {video} decoded only"), done.stderr
    assert len(PoseSequence.load(tmp_path / "p.npz")) < 16


def test_native_log_lines_are_hidden_unless_verbose(tmp_path):
    """A normal run's stderr is the tool's own (progress and its result line); -v adds mediapipe's native lines."""
    video = tmp_path / "clip.mp4"
    write_video(video, _person_moving_right(4, 10), 12)
    stderr = {}
    for flags in ([], ["-v"]):
        done = subprocess.run([sys.executable, "-m", "apps.cli", NAME, *flags, str(video), "--out",
                               str(tmp_path / "p.npz")], capture_output=True, text=True, cwd=Path(__file__).parents[2],
                              timeout=300)
        assert done.returncode == 0, done.stderr
        stderr[tuple(flags)] = done.stderr
    assert not NATIVE.search(stderr[()]), stderr[()]
    assert stderr[()].splitlines()[-1].startswith(f"Wrote {tmp_path / 'p.npz'}: 4 frames")
    assert NATIVE.search(stderr[("-v",)]), stderr[("-v",)]
