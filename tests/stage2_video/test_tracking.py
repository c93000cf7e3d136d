"""Person selection and tracking logic, with a scripted stand-in for BlazePose (no model needed)."""

import numpy as np
import pytest

from dancesynth.core.errors import DancesynthError
from dancesynth.core.skeleton import JOINT_INDEX
from stage2_video.tracking import Box, PersonTracker, TrackerConfig, choose_target, find_people, pose_box, torso

J = JOINT_INDEX
W, H = 640, 360


def person(cx: float, cy: float, size: float) -> np.ndarray:
    """A stick pose with its neck at (cx, cy) and a torso ``size`` pixels long."""
    pose = np.zeros((25, 3), np.float32)
    for name, (dx, dy) in {"Neck": (0, 0), "Nose": (0, -0.5), "RShoulder": (-0.5, 0), "LShoulder": (0.5, 0),
                           "MidHip": (0, 1), "RHip": (-0.3, 1), "LHip": (0.3, 1)}.items():
        pose[J[name]] = (cx + dx * size, cy + dy * size, 1.0)
    return pose


class ScriptedEstimator:
    """Plays BlazePose on synthetic frames that carry their frame index in the red channel.

    ``scenes[t]`` lists the people in frame t. ``detect`` returns the first listed person whose neck lies in
    the searched box and has not been blanked out (green channel changed by :func:`find_people`); ``track``
    returns ``tracked[t]`` when given, else behaves like ``detect``.
    """

    def __init__(self, scenes, tracked=None):
        self.scenes, self.tracked = scenes, tracked or {}
        self.resets = 0

    def detect(self, frame, box=None):
        t = int(frame[..., 0].max())
        for pose in self.scenes[t]:
            x, y = pose[J["Neck"], :2].astype(int)
            inside = box is None or (abs(x - box.cx) < box.side / 2 and abs(y - box.cy) < box.side / 2)
            if inside and 0 <= x < W and 0 <= y < H and frame[y, x, 1] == 255:
                return pose
        return None

    def track(self, frame, box):
        t = int(frame[..., 0].max())
        return self.tracked[t] if t in self.tracked else self.detect(frame, box)

    def reset(self):
        self.resets += 1


def frame(t: int) -> np.ndarray:
    image = np.zeros((H, W, 3), np.uint8)
    image[..., 0] = t
    image[..., 1] = 255
    image[0, 0, 1] = 0  # so the blanking colour (the mean) differs from 255
    return image


def run(tracker, n):
    return [tracker.step(frame(t)) for t in range(n)]


def test_pose_box_and_torso():
    pose = person(100, 50, 40)
    box = pose_box(pose)
    assert (box.cx, box.cy, box.side) == (100, 60, 60)  # nose at y 30 to hips at y 90
    neck, size = torso(pose)
    np.testing.assert_allclose(neck, (100, 50))
    assert size == 40
    assert torso(np.zeros((25, 3), np.float32)) is None
    # Crops are clipped to the frame, never padded.
    assert Box(10, 10, 40).bounds(100, 50) == (0, 0, 30, 30)
    assert Box(90, 40, 40).scaled(2).bounds(100, 50) == (50, 0, 100, 50)


def test_find_people_finds_everyone_and_choose_target_prefers_large_and_central():
    small_centre, big_corner, big_centre = person(330, 150, 30), person(60, 60, 70), person(420, 160, 70)
    scenes = [[small_centre, big_corner, big_centre]]
    people = find_people(frame(0), ScriptedEstimator(scenes))
    assert [p[J["Neck"], 0] for p in people] == [330, 60, 420]
    assert choose_target(people, W, H) is big_centre
    assert choose_target([small_centre, big_corner], W, H) is big_corner
    assert choose_target([], W, H) is None


def test_jump_to_another_person_is_rejected_and_rescued():
    target = [person(300 + 5 * t, 150, 60) for t in range(6)]
    other = person(520, 150, 60)
    scenes = [[target[t], other] for t in range(6)]
    estimator = ScriptedEstimator(scenes, tracked={3: other})
    tracker = PersonTracker(estimator, W, H)
    poses = run(tracker, 6)
    assert all(p is target[t] for t, p in enumerate(poses))
    assert tracker.stats.jumps_rejected == 1 and tracker.stats.rescued == 1


def test_lost_target_is_waited_for_and_reacquired_not_replaced():
    target, other = person(300, 150, 60), person(560, 150, 45)
    scenes = [[target, other]] * 3 + [[other]] * 6 + [[other, target]] * 3
    tracker = PersonTracker(ScriptedEstimator(scenes), W, H)
    poses = run(tracker, 12)
    assert all(p is target for p in poses[:3] + poses[-3:])
    assert all(p is None for p in poses[3:9])
    assert tracker.stats.reacquired == 1 and tracker.stats.missing == 6


def test_a_target_lost_after_wrong_fits_is_reacquired_where_it_was_lost_not_replaced_by_a_stranger():
    """As in a somersault against the sun: BlazePose fits the tumbling body too big for a few frames, loses it,
    and finds it again where it was lost; meanwhile a bigger stranger walks by below it."""
    target = [person(200 + 4 * t, 120, 40) for t in range(10)]
    wrong_fits = {10: person(244, 132, 60), 11: person(248, 146, 72), 12: person(252, 160, 84)}
    stranger, back = person(330, 250, 90), person(240, 130, 40)
    scenes = [[p] for p in target] + [[]] * 3 + [[stranger]] * 12 + [[stranger, back]] * 3
    tracker = PersonTracker(ScriptedEstimator(scenes, tracked=wrong_fits), W, H)
    poses = run(tracker, len(scenes))
    assert all(p is not stranger for p in poses)
    assert all(p is back for p in poses[-3:]) and tracker.stats.reacquired == 1


def test_a_smaller_bystander_is_not_taken_while_the_target_is_hidden_for_a_third_of_a_second():
    target = [person(400 - 10 * t, 120, 70) for t in range(26)]
    bystander = person(260, 280, 40)  # in view throughout, 160 px below where the target is looked for
    scenes = [[target[t], bystander] for t in range(10)] + [[bystander]] * 10 + [
        [bystander, target[t]] for t in range(20, 26)]
    poses = run(PersonTracker(ScriptedEstimator(scenes), W, H), 26)
    assert all(p is None for p in poses[10:20])
    assert all(p is target[t] for t, p in enumerate(poses) if t < 10 or t >= 20)


def test_a_person_growing_steadily_towards_the_camera_is_followed_throughout():
    growing = [person(320, 100, 20 * 1.03 ** t) for t in range(60)]  # 3 % a frame: 5.9 times in 2 s at 30 fps
    tracker = PersonTracker(ScriptedEstimator([[p] for p in growing]), W, H)
    assert all(p is growing[t] for t, p in enumerate(run(tracker, 60)))


def test_crop_follows_the_target_so_a_bigger_person_outside_it_is_never_taken():
    target = [person(150 + 10 * t, 180, 40) for t in range(8)]
    bigger = person(560, 180, 80)
    # The bigger person is listed first: a whole-frame search would return them.
    scenes = [[target[0]]] + [[bigger, target[t]] for t in range(1, 8)]
    tracker = PersonTracker(ScriptedEstimator(scenes), W, H)
    assert all(p is target[t] for t, p in enumerate(run(tracker, 8)))


def test_a_start_pose_picks_whom_to_follow_over_a_bigger_person_in_the_centre():
    target = [person(120 + 10 * t, 180, 30) for t in range(5)]
    bigger = person(330, 160, 80)
    scenes = [[bigger, target[t]] for t in range(5)]
    assert PersonTracker(ScriptedEstimator(scenes), W, H).step(frame(0)) is bigger
    tracker = PersonTracker(ScriptedEstimator(scenes), W, H, start=target[0])
    assert all(p is target[t] for t, p in enumerate(run(tracker, 5)))


def test_two_equally_prominent_people_are_refused_one_clear_target_is_not():
    twins = [[person(250, 150, 60), person(390, 150, 60)]]
    target_video = TrackerConfig(min_lead=1.25)
    with pytest.raises(DancesynthError, match="people of about the same size"):
        PersonTracker(ScriptedEstimator(twins), W, H, target_video).step(frame(0))
    # A third bigger than the other: clearly the dancer.
    clear = [[person(250, 150, 60), person(390, 150, 80)]]
    assert PersonTracker(ScriptedEstimator(clear), W, H, target_video).step(frame(0)) is clear[0][1]
    # Elsewhere (extract-poses, prepare) the likelier one is followed.
    assert PersonTracker(ScriptedEstimator(twins), W, H).step(frame(0)) is not None
