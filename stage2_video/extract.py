"""Video -> BODY_25 PoseSequence with the BlazePose model bundled in mediapipe (CPU, offline).

Pipeline per video: decode upright frames (:mod:`dancesynth.core.media` applies the container's rotation),
follow one person with :class:`stage2_video.tracking.PersonTracker`, map BlazePose's 33 landmarks to
BODY_25, put back the joints that leap away for a few frames (arms or legs swapped back, the rest dropped), fill
joints lost for at most ``max_fill_seconds`` by interpolation in time (longer losses stay absent, so no limb is
drawn where the estimator saw none), smooth (:mod:`stage2_video.smoothing`).

BlazePose -> BODY_25: Neck = mid-shoulders, MidHip = mid-hips (confidence = the smaller of the pair),
heel = heel, big toe = foot index (BlazePose's toe-tip point). BlazePose has no small-toe point, so
LSmallToe / RSmallToe are always absent (confidence 0). Confidence = landmark visibility; landmarks below
``min_visibility`` or outside the frame are absent.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import cv2
import numpy as np

from dancesynth.core.draw import draw_pose
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import require_file
from dancesynth.core.media import VideoWriter, probe_video, read_frames
from dancesynth.core.progress import track
from dancesynth.core.skeleton import JOINT_INDEX, NECK, NUM_JOINTS, ROOT, PoseSequence, interpolate_missing
from stage2_video.smoothing import SmoothingConfig, despike, smooth
from stage2_video.tracking import Box, PersonTracker, TrackerConfig, TrackStats

logger = logging.getLogger(__name__)

# BODY_25 joint -> BlazePose landmark index (mediapipe.solutions.pose.PoseLandmark order).
_BLAZEPOSE_OF_BODY25: dict[str, int] = {
    "Nose": 0, "RShoulder": 12, "RElbow": 14, "RWrist": 16, "LShoulder": 11, "LElbow": 13, "LWrist": 15,
    "RHip": 24, "RKnee": 26, "RAnkle": 28, "LHip": 23, "LKnee": 25, "LAnkle": 27,
    "REye": 5, "LEye": 2, "REar": 8, "LEar": 7, "LBigToe": 31, "LHeel": 29, "RBigToe": 32, "RHeel": 30,
}
_MIDPOINTS = ((NECK, JOINT_INDEX["LShoulder"], JOINT_INDEX["RShoulder"]),
              (ROOT, JOINT_INDEX["LHip"], JOINT_INDEX["RHip"]))
_BODY25_IDX = np.array([JOINT_INDEX[n] for n in _BLAZEPOSE_OF_BODY25])
_BLAZE_IDX = np.array(list(_BLAZEPOSE_OF_BODY25.values()))


@dataclass
class ExtractConfig:
    """Settings of :func:`extract_poses`.

    Attributes:
        min_visibility: BlazePose visibility below which a landmark counts as absent.
        crop_size: side in pixels to which a tracking crop is resampled before BlazePose.
        max_missing_fraction: above this fraction of frames without the person, extraction fails.
        max_fill_seconds: a joint lost for longer than this stays absent instead of being interpolated.
        tracker: person tracking thresholds.
        smoothing: spike removal (before gap filling) and the temporal filter applied after it.
    """

    min_visibility: float = 0.5
    crop_size: int = 384
    max_missing_fraction: float = 0.5
    max_fill_seconds: float = 0.5
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    smoothing: SmoothingConfig = field(default_factory=SmoothingConfig)

    def __post_init__(self) -> None:
        if not (0 <= self.min_visibility <= 1 and 0 <= self.max_missing_fraction <= 1):
            raise DancesynthError("The minimum visibility and the largest missing fraction must be between 0 and 1.")
        if self.max_fill_seconds < 0:
            raise DancesynthError(f"The longest gap to fill must be 0 s or more, got {self.max_fill_seconds} s.")
        if self.crop_size < 64:
            raise DancesynthError(f"The crop size must be at least 64 pixels, got {self.crop_size}.")


def blazepose_to_body25(landmarks: np.ndarray, region: tuple[float, float, float, float],
                        frame_size: tuple[int, int], min_visibility: float) -> np.ndarray:
    """Map BlazePose landmarks to a BODY_25 pose in frame pixels.

    Args:
        landmarks: ``[33, 3]`` x, y normalised to the processed image ([0, 1] inside it) and visibility.
        region: ``(x0, y0, w, h)`` in frame pixels of the image BlazePose saw.
        frame_size: ``(width, height)`` of the frame in pixels; joints outside it are absent.
        min_visibility: visibility below which a joint is absent.

    Returns:
        ``[25, 3]`` float32: x, y in pixels, confidence (0 = absent; small toes are always absent).
    """
    x0, y0, w, h = region
    pts = np.empty((len(landmarks), 3), np.float32)
    pts[:, 0] = x0 + landmarks[:, 0] * w
    pts[:, 1] = y0 + landmarks[:, 1] * h
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < frame_size[0]) & (pts[:, 1] >= 0) & (pts[:, 1] < frame_size[1])
    pts[:, 2] = np.where(inside & (landmarks[:, 2] >= min_visibility), landmarks[:, 2], 0.0)
    out = np.zeros((NUM_JOINTS, 3), np.float32)
    out[_BODY25_IDX] = pts[_BLAZE_IDX]
    for mid, a, b in _MIDPOINTS:
        if out[a, 2] > 0 and out[b, 2] > 0:
            out[mid] = (*((out[a, :2] + out[b, :2]) / 2), min(out[a, 2], out[b, 2]))
    return out


@contextlib.contextmanager
def native_logs_hidden_unless_debug() -> Iterator[None]:
    """Unless this module logs at DEBUG (``-v``), send what native code writes to the process's stderr to
    /dev/null: mediapipe's absl and TF Lite lines (a dozen per graph, at its creation and on later inputs), which
    neither ``GLOG_minloglevel`` nor ``TF_CPP_MIN_LOG_LEVEL`` nor an absl setting silences. Python's own messages
    keep going to the real stderr."""
    if logger.isEnabledFor(logging.DEBUG):
        yield
        return
    python_stderr = sys.stderr
    try:
        python_uses_fd2 = python_stderr.fileno() == 2
    except (AttributeError, OSError, ValueError):  # a replaced stderr (a test's capture) has no descriptor
        python_uses_fd2 = False
    python_stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    os.close(devnull)
    if python_uses_fd2:
        sys.stderr = open(os.dup(saved), "w", buffering=1, encoding=python_stderr.encoding,
                          errors=python_stderr.errors)
    try:
        yield
    finally:
        if python_uses_fd2:
            sys.stderr.close()
            sys.stderr = python_stderr
        os.dup2(saved, 2)
        os.close(saved)


class BlazePose:
    """BlazePose (mediapipe ``model_complexity=1``, the only bundled variant) behind the tracker's interface.

    Two graphs: one in video mode, which tracks between calls, for following the target on a moving crop;
    one in single-image mode for searches. Use as a context manager or call :meth:`close`.
    """

    def __init__(self, min_visibility: float = 0.5, crop_size: int = 384):
        try:
            from mediapipe.python.solutions.pose import Pose
        except ImportError as e:
            raise DancesynthError("mediapipe is not installed; install it with "
                                  "`pip install --no-deps mediapipe==0.10.21` (see the Makefile).") from e
        # Complexity 0 and 2 are not bundled and would try to download; 1 is.
        self._video = Pose(model_complexity=1, static_image_mode=False)
        self._still = Pose(model_complexity=1, static_image_mode=True)
        self.min_visibility = min_visibility
        self.crop_size = crop_size

    def __enter__(self) -> "BlazePose":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._video.close()
        self._still.close()

    def reset(self) -> None:
        self._video.reset()

    def track(self, frame: np.ndarray, box: Box) -> np.ndarray | None:
        return self._run(self._video, frame, box)

    def detect(self, frame: np.ndarray, box: Box | None = None) -> np.ndarray | None:
        return self._run(self._still, frame, box)

    def _run(self, graph, frame: np.ndarray, box: Box | None) -> np.ndarray | None:
        height, width = frame.shape[:2]
        # The crop is clipped to the frame, never padded: BlazePose takes padding for more body and
        # invents hips and legs in it.
        x0, y0, x1, y1 = (0, 0, width, height) if box is None else box.bounds(width, height)
        if x1 - x0 < 2 or y1 - y0 < 2:
            return None
        image = frame[y0:y1, x0:x1]
        if box is not None:
            # Resampled to a fixed size so small people are enlarged and the tracking graph sees steady input.
            s = self.crop_size / max(x1 - x0, y1 - y0)
            image = cv2.resize(image, (max(1, round((x1 - x0) * s)), max(1, round((y1 - y0) * s))),
                               interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_CUBIC)
        region = (float(x0), float(y0), float(x1 - x0), float(y1 - y0))
        result = graph.process(np.ascontiguousarray(image))
        if result.pose_landmarks is None:
            return None
        lms = np.array([(p.x, p.y, p.visibility) for p in result.pose_landmarks.landmark], np.float32)
        return blazepose_to_body25(lms, region, (width, height), self.min_visibility)


@dataclass
class Extraction:
    """What :func:`extract_poses` found.

    Attributes:
        poses: the target person's poses, gaps filled and smoothed, in pixels of the upright frame.
        found: ``[T]`` bool, whether the person was detected in each frame (False = filled by interpolation).
        stats: what the tracker did (see :class:`stage2_video.tracking.TrackStats`).
    """

    poses: PoseSequence
    found: np.ndarray
    stats: TrackStats


def extract_poses(video: str | os.PathLike, config: ExtractConfig | None = None,
                  progress: bool = True) -> Extraction:
    """Extract the main person's BODY_25 poses from every frame of ``video``.

    Raises:
        DancesynthError: the video is missing or unreadable, or the person is absent in more than
            ``config.max_missing_fraction`` of the frames.
    """
    video = require_file(video, "Video")
    info = probe_video(video)
    return extract_frames(read_frames(video), info.fps, (info.width, info.height), config, progress,
                          total=info.num_frames or None, source=str(video))


def extract_frames(frames: Iterable[np.ndarray], fps: float, size: tuple[int, int],
                   config: ExtractConfig | None = None, progress: bool = True, total: int | None = None,
                   source: str = "the input", start: np.ndarray | None = None) -> Extraction:
    """:func:`extract_poses` on decoded frames (RGB uint8 ``[height, width, 3]``, ``size = (width, height)``).

    Used where frames are already in memory (e.g. generated frames), so no lossy re-encoding blurs thin limbs.
    ``start``: the ``[25, 3]`` pose (pixels of the frames) of the person to follow in the first frame
    (:class:`PersonTracker`).

    Raises:
        DancesynthError: the person is absent in more than ``config.max_missing_fraction`` of the frames.
    """
    config = config or ExtractConfig()
    raw, found = [], []
    with native_logs_hidden_unless_debug(), BlazePose(config.min_visibility, config.crop_size) as estimator:
        tracker = PersonTracker(estimator, size[0], size[1], config.tracker, start)
        for frame in track(frames, total=total, desc="extracting poses", unit="frame", disable=not progress):
            pose = tracker.step(frame)
            found.append(pose is not None)
            raw.append(np.zeros((NUM_JOINTS, 3), np.float32) if pose is None else pose)
    found = np.array(found, bool)
    missing = 1.0 - found.mean() if len(found) else 1.0
    if missing > config.max_missing_fraction:
        raise DancesynthError(f"No person was found in {missing:.0%} of the frames in {source}; "
                              "use a video where one person is fully visible.")
    seq = PoseSequence(np.stack(raw), fps, size[0], size[1])
    seq = interpolate_missing(despike(seq, config.smoothing), max_gap=round(config.max_fill_seconds * fps))
    seq = smooth(seq, config.smoothing)
    return Extraction(seq, found, tracker.stats)


def write_preview(video: str | os.PathLike, poses: PoseSequence, out: str | os.PathLike,
                  progress: bool = True) -> None:
    """Write ``out`` (mp4): the frames of ``video`` with ``poses`` drawn over them (OpenPose colours)."""
    with VideoWriter(out, poses.fps, poses.width, poses.height) as writer:  # atomic: temp name, then rename
        frames = track(read_frames(video), total=len(poses), desc="writing preview", unit="frame",
                      disable=not progress)
        for frame, keypoints in zip(frames, poses.keypoints):
            writer.write(draw_pose(frame, keypoints))
