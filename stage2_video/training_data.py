"""Training data for the appearance model from ONE video of the target person.

The frames are framed (crop + resize + pad, see :mod:`stage2_video.framing`) once and cached in the run folder
as a uint8 ``.npy`` memory map, so memory stays flat for long videos and resuming skips the decoding. Poses
are cached as ``poses.npz``. Each cache has a ``<name>.key`` file, written after the cache is complete, naming
what it was made from (the video's SHA-256 and the options that shape it), so a cache left by an interrupted
run or made from another video is rebuilt instead of used. The split is by time: the last ``val_fraction`` of
the video is held out, and the last ``select_fraction`` of the rest chooses the checkpoint (:func:`selection_split`).
Frames where the person's torso is absent or has an implausible length (e.g. a jump the
pose estimator lost or mistook) are neither trained on nor scored: their label maps would teach the model to
draw the person from a skeleton that is not theirs.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import logging
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import torch
from torch.utils.data import Dataset

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.media import probe_video, read_frames
from dancesynth.core.progress import track
from dancesynth.core.skeleton import PoseSequence
from stage2_video.framing import Framing, VideoFraming, condition, plate_crop, usable_frames
from stage2_video.prior import FrameBank, PriorRenderer, bank_keypoints, scaled_framing

logger = logging.getLogger(__name__)

POSES_FILE = "poses.npz"
# latest.json's kind of an appearance model's run (stage2_video.train writes it, the readers check it).
KIND = "stage2"
# While a frame is learnt, the frame bank returns no frame within this many seconds of it: the network must learn
# to repair a warp of another moment, as at render time, not to copy its target.
EXCLUDE_SECONDS = 1.0
# A target video's person must score this many times any other person's prominence when first found.
TARGET_MIN_LEAD = 1.25
KEY_SUFFIX = ".key"


def frames_file(framing: VideoFraming) -> str:
    return f"frames_{framing.out_width}x{framing.out_height}.npy"


def to_tensor(image: np.ndarray) -> torch.Tensor:
    """``[H, W, C]`` uint8 -> ``[C, H, W]`` float32 in [-1, 1]."""
    return torch.from_numpy(np.array(image, np.uint8)).permute(2, 0, 1).float().div(127.5).sub(1.0)


def to_image(tensor: torch.Tensor) -> np.ndarray:
    """``[3, H, W]`` float in [-1, 1] -> ``[H, W, 3]`` uint8 (rounded, clipped)."""
    x = tensor.detach().float().clamp(-1, 1).add(1).mul(127.5).round().to(torch.uint8)
    return x.permute(1, 2, 0).cpu().numpy()


@functools.lru_cache(maxsize=8)
def _sha256(path: str, size: int, mtime_ns: int) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def video_digest(video: Path) -> str:
    """SHA-256 (hex) of the video file's bytes; remembered while the file's size and modification time stay."""
    try:
        info = os.stat(video)
        return _sha256(str(Path(video).resolve()), info.st_size, info.st_mtime_ns)
    except OSError as e:
        raise DancesynthError(f"Could not read the target video {video} ({e.strerror or e}); check the path.") from e


def _cache_key(video: Path, **options) -> str:
    return json.dumps({"video_sha256": video_digest(video), **options}, sort_keys=True, default=str)


def _key_file(cache: Path) -> Path:
    return cache.with_name(cache.name + KEY_SUFFIX)


def _loads(cache: Path) -> bool:
    """Whether the array file ``cache`` opens: one cut short (a full disk, a copy stopped midway) does not, and
    is then made again instead of failing later. Other files are read by their own loaders."""
    if cache.suffix != ".npy":
        return True
    try:
        np.load(cache, mmap_mode="r")
    except (ValueError, OSError, EOFError):
        return False
    return True


def _is_cached(cache: Path, key: str) -> bool:
    """Whether ``cache`` is complete (it loads) and was made from what ``key`` names."""
    marker = _key_file(cache)
    return cache.is_file() and marker.is_file() and marker.read_text() == key and _loads(cache)


@contextlib.contextmanager
def _rebuilding(cache: Path, key: str) -> Iterator[None]:
    """Around rewriting ``cache``: its key file goes first and is written again only once the cache is complete."""
    _key_file(cache).unlink(missing_ok=True)
    yield
    with atomic_path(_key_file(cache)) as tmp:
        tmp.write_text(key)


def cache_file(cache: Path, video: Path, write: Callable[[Path], None], **options) -> None:
    """Make ``cache`` with ``write(temporary path)`` unless it is complete and was made from ``video`` and
    ``options`` (its key file says so); the file appears atomically, its key file after it."""
    key = _cache_key(video, **options)
    if _is_cached(cache, key):
        return
    with _rebuilding(cache, key), atomic_path(cache) as tmp:
        write(tmp)


def poses_digest(poses: PoseSequence) -> str:
    """SHA-256 (hex) of the pose array and its canvas: what a plate made from these poses depends on."""
    digest = hashlib.sha256(np.ascontiguousarray(poses.keypoints).tobytes())
    digest.update(f"{poses.width}x{poses.height}".encode())
    return digest.hexdigest()


def load_or_extract_poses(video: Path, run_dir: Path, poses: Path | None) -> PoseSequence:
    """The target's poses: ``poses`` when given (e.g. ground truth of a synthetic video), else the run's cache
    when it was made for this video, else extracted from the video (then cached as ``RUN_DIR/poses.npz``)."""
    cache = run_dir / POSES_FILE
    key = _cache_key(video)
    if poses is not None:
        seq = PoseSequence.load(poses)
    elif _is_cached(cache, key):
        return PoseSequence.load(cache)
    else:
        # mediapipe is heavy; import only when extracting
        from stage2_video.extract import ExtractConfig, extract_poses
        from stage2_video.tracking import TrackerConfig

        seq = extract_poses(video, ExtractConfig(tracker=TrackerConfig(min_lead=TARGET_MIN_LEAD))).poses
    with _rebuilding(cache, key):
        seq.save(cache)
    return seq


def check_poses_match(seq: PoseSequence, video: Path) -> PoseSequence:
    """Poses must be measured on the video's canvas (the frame count is checked by :func:`cache_frames`)."""
    info = probe_video(video)
    if (seq.width, seq.height) != (info.width, info.height):
        raise DancesynthError(
            f"The poses are for a {seq.width}x{seq.height} canvas but {video} is {info.width}x{info.height}; "
            "pass the poses extracted from this video.")
    return seq


def framed_key(framing: VideoFraming, boxes: list[Framing]) -> dict:
    """What a cache of framed images depends on besides the video: the framing, the frame count and where each
    frame's box sits (a following box moves with the poses)."""
    corners = hashlib.sha256(np.array([(f.x0, f.y0) for f in boxes], np.int64).tobytes()).hexdigest()
    return {"framing": framing.to_dict(), "frames": len(boxes), "boxes": corners}


def cache_frames(video: Path, framing: VideoFraming, run_dir: Path, poses: PoseSequence) -> np.ndarray:
    """Framed uint8 frames ``[T, H, W, 3]`` (memory-mapped; frame t framed as ``framing.frames(poses)[t]``),
    decoded once and cached in ``run_dir``; a cache made from another video, framing or poses is rebuilt."""
    path = run_dir / frames_file(framing)
    boxes = framing.frames(poses)
    num_frames = len(boxes)
    key = _cache_key(video, **framed_key(framing, boxes))
    if _is_cached(path, key):
        return np.load(path, mmap_mode="r")
    count = 0
    with _rebuilding(path, key), atomic_path(path) as tmp:
        out = np.lib.format.open_memmap(tmp, mode="w+", dtype=np.uint8,
                                        shape=(num_frames, framing.out_height, framing.out_width, 3))
        for frame in track(read_frames(video), total=num_frames, desc="frames", unit="frame"):
            if count == num_frames:
                break
            out[count] = boxes[count].image(frame)
            count += 1
        out.flush()
        del out
        if count < num_frames:
            raise DancesynthError(f"{video} has {count} frames but the poses have {num_frames}; "
                                  "pass the poses extracted from this video.")
    return np.load(path, mmap_mode="r")


def split_ranges(num_frames: int, val_fraction: float) -> tuple[range, range]:
    """(train, validation) frame ranges: validation is the last ``val_fraction`` of the video (>= 2 frames)."""
    n_val = max(2, int(round(num_frames * val_fraction)))
    if num_frames - n_val < 2:
        raise DancesynthError(f"The video has only {num_frames} frames; use a target video of at least a few seconds.")
    return range(0, num_frames - n_val), range(num_frames - n_val, num_frames)


def selection_split(train: range, fraction: float) -> tuple[range, range]:
    """(learnt, selection) ranges of the training range ``train``: the selection is its last ``fraction`` (none at
    0, else >= 2 frames), not learnt from but in the frame bank, scoring checkpoints so the trainer keeps the best
    without looking at the held-out frames."""
    if fraction <= 0:
        return train, range(train.stop, train.stop)
    n_select = max(2, int(round(len(train) * fraction)))
    if len(train) - n_select < 2:
        raise DancesynthError(f"The video has only {len(train)} frames to learn from; use a target video of at least "
                              "a few seconds.")
    return range(train.start, train.stop - n_select), range(train.stop - n_select, train.stop)


def rendered_checkpoint(meta: dict) -> dict:
    """The step an appearance model's checkpoint ``meta`` renders with and that step's held-out ``ssim`` / ``psnr``
    (where it was validated): meta ``best`` where training kept an earlier step, else the latest step."""
    return meta.get("best") or {**(meta.get("validation") or {}), "step": meta.get("step")}


def frame_bank(frames: np.ndarray, masks: np.ndarray, poses: PoseSequence, bank_framing: VideoFraming,
               members: range, candidates: int = 1) -> FrameBank:
    """The :class:`FrameBank` of a target: its ``[T, H, W, 3]`` frames and ``[T, H, W]`` person masks framed by
    ``bank_framing`` (the model's framing at the prior's scale), holding the frames of ``members`` (the training
    range) whose pose is usable and whose mask is not empty; ``candidates``: frames per prior
    (:class:`FrameBank`)."""
    usable = usable_frames(poses)
    kept = [t for t in members if usable[t] and masks[t].any()]
    if not kept:
        raise DancesynthError("The person is found in too few frames of the target video to learn from; use a "
                              "video where one person stays fully visible.")
    bank = FrameBank(frames, masks, bank_keypoints(poses.keypoints, bank_framing.frames(poses)), np.array(kept),
                     candidates=candidates, scene=poses.keypoints)
    hidden = bank.hidden_parts()
    if hidden:
        named = hidden[0] if len(hidden) == 1 else f"{', '.join(hidden[:-1])} and {hidden[-1]}"
        _warn_once(f"The target video shows the person's {named} in fewer than half of its frames "
                   "(hidden behind something, or outside the picture), so a dance shows the background there; a video "
                   "where the whole body is visible gives a whole person.")
    return bank


@functools.cache
def _warn_once(message: str) -> None:
    """Log ``message`` as a warning the first time only: training and rendering in one process build the bank
    twice."""
    logger.warning(message)


def prior_images(renderer: PriorRenderer, keypoints: np.ndarray, bank_framing: Framing, plate: np.ndarray,
                 model_size: tuple[int, int], frame: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The warped prior of one ``[25, 3]`` pose (canvas pixels) framed by ``bank_framing``, over that framing's
    crop of the ``[H, W, 3]`` ``plate``: ``[h2, w2, 4]`` uint8 at the bank's size (RGB over the plate, alpha) and
    the same resized to ``model_size`` (width, height). ``frame``: the video frame being learnt (excluded)."""
    scene = np.asarray(keypoints, np.float32)
    pose = np.c_[bank_framing.points(scene[:, :2]), scene[:, 2]]
    high = renderer(pose, plate_crop(bank_framing, plate), frame, scene)
    return high, cv2.resize(high, model_size, interpolation=cv2.INTER_AREA)


@dataclass
class TargetVideo:
    """Framed frames and poses of the target video; ``framings[t]`` framed frame t, ``usable[t]`` says whether
    frame t is fit to learn from (:func:`usable_frames`); ``plate`` is the scene's background (canvas size) for
    models conditioned on it, else None; ``bank`` the frame bank for models conditioned on the warped prior
    (:mod:`stage2_video.prior`), framed by ``framing`` at ``prior_scale`` times the model's size."""

    frames: np.ndarray
    poses: PoseSequence
    framing: VideoFraming
    plate: np.ndarray | None = None
    bank: FrameBank | None = None
    prior_scale: int = 1
    framings: list[Framing] = field(init=False)
    bank_framings: list[Framing] = field(init=False)
    usable: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.framings = self.framing.frames(self.poses)
        self.bank_framings = scaled_framing(self.framing, self.prior_scale).frames(self.poses)
        self.usable = usable_frames(self.poses)

    def renderer(self) -> PriorRenderer | None:
        """A fresh prior renderer that never retrieves frames near the one being learnt (None without a bank)."""
        if self.bank is None:
            return None
        return PriorRenderer(self.bank, exclude_frames=round(EXCLUDE_SECONDS * self.poses.fps))


class FramePairs(Dataset):
    """Consecutive (previous, current) training pairs inside one frame range, both frames usable.

    Item: ``(cond_prev, frame_prev, cond_cur, frame_cur)``, float32 in [-1, 1]: frames ``[3, H, W]``, conditions
    ``[C, H, W]`` (the label map, + the background crop, + the warped prior; :func:`stage2_video.framing.condition`).
    """

    def __init__(self, target: TargetVideo, frames: range) -> None:
        self.target = target
        self.starts = [t for t in range(frames.start, frames.stop - 1) if target.usable[t] and target.usable[t + 1]]

    def __len__(self) -> int:
        return len(self.starts)

    def item(self, t: int, renderer: PriorRenderer | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Condition and frame of frame ``t``; ``renderer`` carries the retrieval over from the previous frame."""
        return self.sample(t, renderer)[:2]

    def sample(self, t: int, renderer: PriorRenderer | None = None
               ) -> tuple[torch.Tensor, torch.Tensor, np.ndarray | None]:
        """:meth:`item`'s condition and frame, and the ``[h2, w2, 4]`` uint8 warped prior at the bank's size it was
        made from (:func:`prior_images`; None without a bank)."""
        target = self.target
        high = low = None
        if target.bank is not None:
            size = (target.framings[t].out_width, target.framings[t].out_height)
            high, low = prior_images(renderer or target.renderer(), target.poses.keypoints[t], target.bank_framings[t],
                                     target.plate, size, frame=t)
        label = condition(target.poses.keypoints[t], target.framings[t], target.plate, low)
        return to_tensor(label), to_tensor(target.frames[t]), high

    def __getitem__(self, i: int) -> tuple[torch.Tensor, ...]:
        t = self.starts[i]
        renderer = self.target.renderer()
        return (*self.item(t, renderer), *self.item(t + 1, renderer))
