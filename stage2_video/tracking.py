"""Following one person through a video with a single-person pose estimator.

BlazePose returns at most one person per image and, when several are visible, may switch to another one
between frames. The tracker here keeps one target:

* **Choosing the target** (:func:`find_people`, :func:`choose_target`): detect a person on the whole frame,
  blank out their box and detect again, until nobody new is found; then keep the person with the best
  "large and near the centre" score.
* **Following** (:class:`PersonTracker`): the estimator runs on a square crop around the target's
  predicted box, so people outside the crop cannot be picked up at all.
* **Jump detection**: a pose whose neck moved more than ``jump_distance`` torso lengths from the prediction,
  or whose torso size differs by more than ``jump_scale`` times from the target's (the median of its last
  :data:`SIZE_HISTORY` poses', so a few wrong fits running cannot grow it), is another person (or a wrong fit).
  It is rejected, a slower single-image search is run on the same crop, and when that fails too the frame is
  marked missing.
* **Recovery**: after ``reacquire_after`` consecutive missing frames the whole frame is searched again and,
  among the people of similar torso size, the one closest to where the target was last seen is taken; the
  allowed distance grows with the time the target has been unseen, around where it was last seen moved on at
  its last speed for ``reacquire_after`` frames at most.

Limits: two people overlapping in the image can still be confused (a crop then holds both); a person who
leaves the frame and comes back elsewhere is re-acquired only as "closest to the last position", and one
who comes back much nearer or farther from the camera (torso size changed by more than ``jump_scale``) is
not re-acquired at all; a person whose size doubles within about half :data:`SIZE_HISTORY` frames (a fast
zoom) is lost; people much smaller than a tenth of the frame height may be missed by the whole-frame search.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import JOINT_INDEX, NECK, ROOT

_LSHOULDER, _RSHOULDER = JOINT_INDEX["LShoulder"], JOINT_INDEX["RShoulder"]
# Accepted poses whose median torso size is the target's: outlasts 10 wrong fits running, follows a real change late.
SIZE_HISTORY = 21


@dataclass(frozen=True)
class Box:
    """A square image region: centre and side length, in pixels of the frame."""

    cx: float
    cy: float
    side: float

    def scaled(self, factor: float) -> "Box":
        """The same centre, side multiplied by ``factor``."""
        return Box(self.cx, self.cy, self.side * factor)

    def bounds(self, width: int, height: int) -> tuple[int, int, int, int]:
        """Integer ``(x0, y0, x1, y1)`` clipped to a ``width`` x ``height`` frame."""
        half = self.side / 2
        x0, y0 = max(0, int(self.cx - half)), max(0, int(self.cy - half))
        x1, y1 = min(width, int(np.ceil(self.cx + half))), min(height, int(np.ceil(self.cy + half)))
        return x0, y0, x1, y1


class PoseEstimator(Protocol):
    """What the tracker needs from a single-person pose estimator. Poses are ``[25, 3]`` (pixels, confidence)."""

    def track(self, frame: np.ndarray, box: Box) -> np.ndarray | None:
        """Video-mode estimate on ``box`` of an RGB ``[H, W, 3]`` frame (uses the previous call's result)."""

    def detect(self, frame: np.ndarray, box: Box | None = None) -> np.ndarray | None:
        """Single-image estimate on ``box`` (``None``: the whole frame)."""

    def reset(self) -> None:
        """Forget the video-mode state (the next :meth:`track` call starts afresh)."""


def pose_box(pose: np.ndarray) -> Box | None:
    """The square around a ``[25, 3]`` pose's present joints (confidence > 0); ``None`` if fewer than 2."""
    present = pose[pose[:, 2] > 0, :2]
    if len(present) < 2:
        return None
    lo, hi = present.min(axis=0), present.max(axis=0)
    centre = (lo + hi) / 2
    return Box(float(centre[0]), float(centre[1]), float(max(hi - lo)))


def torso(pose: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The tracking anchor of a ``[25, 3]`` pose: neck position (pixels) and torso size (pixels).

    Torso size is the larger of shoulder width and neck-to-mid-hip length, so it stays meaningful for
    upper-body shots (no hips) and side views (narrow shoulders). ``None`` when the neck is absent.
    """
    if pose[NECK, 2] <= 0:
        return None
    size = float(np.linalg.norm(pose[_LSHOULDER, :2] - pose[_RSHOULDER, :2]))
    if pose[ROOT, 2] > 0:
        size = max(size, float(np.linalg.norm(pose[NECK, :2] - pose[ROOT, :2])))
    return pose[NECK, :2].astype(np.float64), max(size, 1.0)


def find_people(frame: np.ndarray, estimator: PoseEstimator, max_people: int = 4) -> list[np.ndarray]:
    """Every person the estimator finds in an RGB ``[H, W, 3]`` frame, by detect-and-blank-out.

    Each found person's box (enlarged by 20 %) is filled with the frame's mean colour before the next
    search. Returns ``[25, 3]`` poses in frame pixels, in the order found (at most ``max_people``).
    """
    work = frame.copy()
    fill = frame.reshape(-1, frame.shape[-1]).mean(axis=0).astype(frame.dtype)
    people: list[np.ndarray] = []
    while len(people) < max_people:
        pose = estimator.detect(work)
        box = None if pose is None or torso(pose) is None else pose_box(pose)
        if box is None:
            break
        people.append(pose)
        x0, y0, x1, y1 = box.scaled(1.2).bounds(frame.shape[1], frame.shape[0])
        if x1 <= x0 or y1 <= y0:
            break
        work[y0:y1, x0:x1] = fill
    return people


def target_score(pose: np.ndarray, width: int, height: int) -> float:
    """How much a pose looks like "the" dancer: torso size (pixels) discounted by distance from the centre.

    The discount is ``1 / (1 + 2 d)`` with ``d`` the neck's distance from the frame centre in units of the
    half-diagonal, so a person at a corner counts a third of one of the same size in the middle.
    """
    anchor = torso(pose)
    if anchor is None:
        return 0.0
    neck, size = anchor
    d = float(np.hypot(neck[0] - width / 2, neck[1] - height / 2) / (np.hypot(width, height) / 2))
    return size / (1.0 + 2.0 * d)


def choose_target(people: list[np.ndarray], width: int, height: int) -> np.ndarray | None:
    """The largest person near the centre (:func:`target_score`), or ``None`` if the list is empty."""
    if not people:
        return None
    return max(people, key=lambda p: target_score(p, width, height))


@dataclass
class TrackerConfig:
    """Tracking thresholds.

    Attributes:
        crop_margin: side of the tracking crop as a multiple of the target's box side.
        jump_distance: largest neck displacement from the prediction, in torso lengths, for the same person.
        jump_scale: largest change factor of torso size (vs the median of the last :data:`SIZE_HISTORY` accepted
            poses') for the same person.
        lost_drift: extra neck displacement allowed per missing frame, in torso lengths (0.1: 3 a second at 30
            fps, a sprint; at 0.2 a bystander half the size came within reach during a 10-frame occlusion).
        reacquire_after: consecutive missing frames before the whole frame is searched again.
        max_people: most people looked for by a whole-frame search.
        min_lead: when set, the target's :func:`target_score` must exceed every other person's by this factor
            when it is first chosen; otherwise whom to follow is a guess and extraction stops with an error (set
            for a target person's video, where following the wrong one would teach the wrong appearance).
    """

    crop_margin: float = 1.6
    jump_distance: float = 1.0
    jump_scale: float = 2.0
    lost_drift: float = 0.1
    reacquire_after: int = 5
    max_people: int = 4
    min_lead: float | None = None


@dataclass
class _Target:
    neck: np.ndarray
    size: float
    box: Box
    velocity: np.ndarray  # pixels per frame, of the neck


@dataclass
class TrackStats:
    """Counters of what the tracker did over a video, in frames.

    Attributes:
        tracked: found by the video-mode estimate on the tracking crop.
        rescued: the video-mode estimate failed or was another person, the single-image search on the crop
            found the target.
        jumps_rejected: the video-mode estimate was rejected as another person (or a wrong fit).
        reacquired: the target was found again by a whole-frame search after being lost.
        missing: the target was not found (filled later by interpolation).
    """

    tracked: int = 0
    rescued: int = 0
    jumps_rejected: int = 0
    reacquired: int = 0
    missing: int = 0


class PersonTracker:
    """Follows one person, frame by frame. Call :meth:`step` once per frame in order."""

    def __init__(self, estimator: PoseEstimator, width: int, height: int, config: TrackerConfig | None = None,
                 start: np.ndarray | None = None):
        """``start``: the ``[25, 3]`` pose (pixels) of the person to follow, where they stand in the first frame:
        it is followed from there (no whole-frame search, no ``min_lead`` check); None, or a pose without a neck or
        with fewer than 2 joints: the largest person near the centre (:func:`choose_target`)."""
        self.estimator = estimator
        self.width, self.height = width, height
        self.config = config or TrackerConfig()
        self.stats = TrackStats()
        self._target: _Target | None = None
        self._missing_run = 0
        # A median, not an average: wrong fits running (a somersault against the sun) must not grow the target.
        self._sizes: deque[float] = deque(maxlen=SIZE_HISTORY)
        if start is not None and torso(np.asarray(start)) is not None and pose_box(np.asarray(start)) is not None:
            self._accept(np.asarray(start))

    def step(self, frame: np.ndarray) -> np.ndarray | None:
        """The target's ``[25, 3]`` pose in an RGB ``[H, W, 3]`` frame (pixels), or ``None`` if not found."""
        if self._target is None or self._missing_run >= self.config.reacquire_after:
            pose = self._acquire(frame)
        else:
            pose = self._follow(frame)
        if pose is None:
            self._missing_run += 1
            self.stats.missing += 1
            return None
        self._accept(pose)
        return pose

    def _predicted(self) -> tuple[np.ndarray, Box]:
        t = self._target
        # Held after the crop's frames: a lost target's last speed (often a wrong fit's) sends the search off the frame.
        shift = t.velocity * min(self._missing_run + 1, self.config.reacquire_after)
        return t.neck + shift, Box(t.box.cx + shift[0], t.box.cy + shift[1], t.box.side)

    def _is_same_person(self, pose: np.ndarray) -> bool:
        anchor = torso(pose)
        if anchor is None:
            return False
        neck, size = anchor
        predicted, _ = self._predicted()
        t = self._target
        ratio = max(size, t.size) / min(size, t.size)
        # Allow more drift the longer the target has been unseen.
        reach = t.size * (self.config.jump_distance + self.config.lost_drift * self._missing_run)
        return bool(np.linalg.norm(neck - predicted) <= reach and ratio <= self.config.jump_scale)

    def _follow(self, frame: np.ndarray) -> np.ndarray | None:
        _, box = self._predicted()
        crop = box.scaled(self.config.crop_margin)
        pose = self.estimator.track(frame, crop)
        if pose is not None and self._is_same_person(pose):
            self.stats.tracked += 1
            return pose
        if pose is not None:
            self.stats.jumps_rejected += 1
        pose = self.estimator.detect(frame, crop)
        if pose is not None and self._is_same_person(pose):
            # The video-mode state followed something else; restart it on the rescued pose.
            self.estimator.reset()
            self.stats.rescued += 1
            return pose
        return None

    def _acquire(self, frame: np.ndarray) -> np.ndarray | None:
        people = find_people(frame, self.estimator, self.config.max_people)
        if self._target is None:
            pose = choose_target(people, self.width, self.height)
            self._check_lead(people)
        else:
            last = self._target.neck
            same = [p for p in people if self._is_same_person(p)]
            pose = min(same, key=lambda p: float(np.linalg.norm(torso(p)[0] - last)), default=None)
        if pose is not None:
            self.estimator.reset()
            if self._target is not None:
                self.stats.reacquired += 1
        return pose

    def _check_lead(self, people: list[np.ndarray]) -> None:
        scores = sorted((target_score(p, self.width, self.height) for p in people), reverse=True)
        lead = self.config.min_lead
        if lead is not None and len(scores) > 1 and scores[0] < lead * scores[1]:
            raise DancesynthError(f"The video shows {len(scores)} people of about the same size near the centre, "
                                  "so it is unclear whom to learn; crop or trim it so that one person stands out.")

    def _accept(self, pose: np.ndarray) -> None:
        neck, size = torso(pose)
        box = pose_box(pose)
        # At least two torso lengths, so a pose with few joints present still gets a crop holding the body.
        box = Box(box.cx, box.cy, max(box.side, 2.0 * size))
        if self._target is not None and self._missing_run < self.config.reacquire_after:
            t = self._target
            step = (neck - t.neck) / (self._missing_run + 1)
            velocity = 0.5 * t.velocity + 0.5 * step
            # A running average: BlazePose's limbs (hence box) can jump between frames, and one odd frame must not
            # shrink the crop onto a limb.
            box = Box(box.cx, box.cy, 0.7 * t.box.side + 0.3 * box.side)
        else:
            velocity = np.zeros(2)
            self._sizes.clear()  # found again by a whole-frame search: it starts afresh, as its speed does
        self._sizes.append(size)
        self._target = _Target(neck, float(np.median(self._sizes)), box, velocity)
        self._missing_run = 0
