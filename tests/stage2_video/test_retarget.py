"""Bone-length retargeting: the target's bone lengths, the dance's joint angles and a scaled root trajectory."""

import numpy as np
import pytest

from dancesynth.core.motion import bone_lengths
from dancesynth.core.skeleton import BODY25_LIMBS, BODY25_TREE, JOINT_INDEX, ROOT, PoseSequence
from stage2_video.normalize import fit_normalization
from stage2_video.render import load_appearance_model
from stage2_video.retarget import body_height, retarget, retarget_onto, target_bone_lengths

ARM_BONES = [BODY25_LIMBS.index((JOINT_INDEX[a], JOINT_INDEX[b]))
             for a, b in (("RShoulder", "RElbow"), ("RElbow", "RWrist"), ("LShoulder", "LElbow"), ("LElbow", "LWrist"))]
SMALL_TOE_BONES = [BODY25_LIMBS.index((JOINT_INDEX[a], JOINT_INDEX[b]))
                   for a, b in (("LBigToe", "LSmallToe"), ("RBigToe", "RSmallToe"))]


@pytest.fixture
def standing(make_poses) -> np.ndarray:
    """``[25, 2]`` a standing figure, about 200 px tall."""
    return make_poses(frames=1).xy[0].astype(np.float64) * 4.0


def dance(standing: np.ndarray, lengths: np.ndarray, frames: int = 40, legs_move: bool = True,
          size: tuple[int, int] = (640, 480)) -> PoseSequence:
    """Bones of fixed ``lengths`` turning smoothly away from ``standing``'s directions (the arms most), the root
    wandering about the canvas centre: a dance on a rigid skeleton."""
    t = np.arange(frames)[:, None] / 15.0
    rng = np.random.default_rng(0)
    xy = np.zeros((frames, 25, 2))
    xy[:, ROOT] = np.concatenate([size[0] / 2 + 60 * np.sin(1.3 * t), size[1] / 2 + 15 * np.cos(2.1 * t)], axis=1)
    for bone, parent, child in BODY25_TREE:
        base = standing[child] - standing[parent]
        swing = 1.2 if bone in ARM_BONES else 0.4 if legs_move else 0.0
        angle = np.arctan2(base[1], base[0]) + swing * np.sin(rng.uniform(1, 4) * t + rng.uniform(0, 6))
        xy[:, child] = xy[:, parent] + lengths[bone] * np.concatenate([np.cos(angle), np.sin(angle)], axis=1)
    return PoseSequence(np.concatenate([xy, np.ones((frames, 25, 1))], axis=-1), 15.0, *size)


def directions(xy: np.ndarray) -> np.ndarray:
    """``[T, B, 2]`` unit vector of each bone, parent to child."""
    parent, child = np.array(BODY25_LIMBS).T
    v = xy[:, child].astype(np.float64) - xy[:, parent]
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def own_lengths(standing: np.ndarray) -> np.ndarray:
    return bone_lengths(standing[None])[0]


def test_an_arm_twice_too_long_comes_out_at_the_targets_length_with_its_angles(standing):
    target = own_lengths(standing)
    stretched = target.copy()
    stretched[ARM_BONES] *= 2
    source = dance(standing, stretched)
    out = retarget(source, target)
    np.testing.assert_allclose(bone_lengths(out.xy), np.broadcast_to(target, (len(out), len(target))), rtol=1e-4)
    # Every bone keeps its direction, so every angle between consecutive bones (e.g. the elbow's) is unchanged.
    np.testing.assert_allclose(directions(out.xy), directions(source.xy), atol=1e-5)
    elbow = [BODY25_LIMBS.index(b) for b in ((2, 3), (3, 4))]
    cos_elbow = lambda xy: np.sum(directions(xy)[:, elbow[0]] * directions(xy)[:, elbow[1]], axis=-1)
    np.testing.assert_allclose(cos_elbow(out.xy), cos_elbow(source.xy), atol=1e-5)
    # Arms are not part of the body height, so the root trajectory is unchanged.
    np.testing.assert_allclose(out.xy[:, ROOT], source.xy[:, ROOT], atol=1e-4)
    assert (out.width, out.height, out.fps) == (source.width, source.height, source.fps)


def test_root_trajectory_is_scaled_by_body_height_about_its_mean(standing):
    lengths = own_lengths(standing)
    source = dance(standing, lengths)
    out = retarget(source, 0.5 * lengths)
    assert body_height(0.5 * lengths) == pytest.approx(0.5 * body_height(lengths))
    center = source.xy[:, ROOT].mean(axis=0)
    np.testing.assert_allclose(out.xy[:, ROOT], center + 0.5 * (source.xy[:, ROOT] - center), atol=1e-3)
    np.testing.assert_allclose(bone_lengths(out.xy), np.broadcast_to(0.5 * lengths, (len(out), len(lengths))),
                               rtol=1e-4)


def test_a_dance_retargeted_onto_its_own_lengths_is_unchanged(standing):
    source = dance(standing, own_lengths(standing) * 1.3)
    out = retarget(source, target_bone_lengths(source))
    np.testing.assert_allclose(out.keypoints, source.keypoints, atol=1e-3)


def test_absent_joints_stay_absent_and_the_body_keeps_one_size(standing):
    lengths = own_lengths(standing)
    stretched = lengths.copy()
    stretched[ARM_BONES] *= 2
    kp = dance(standing, stretched).keypoints.copy()
    elbow, wrist, shoulder = JOINT_INDEX["LElbow"], JOINT_INDEX["LWrist"], JOINT_INDEX["LShoulder"]
    kp[5:10, elbow] = (0.0, 0.0, 0.0)  # dropped detections at the canvas origin
    kp[12, ROOT] = (0.0, 0.0, 0.0)
    source = PoseSequence(kp, 15.0, 640, 480)
    out = retarget(source, 0.8 * lengths)  # a smaller body: the root trajectory shrinks too
    np.testing.assert_array_equal(out.confidence, source.confidence)
    # Every bone is at its new length in every frame, also where one of its joints was dropped ...
    np.testing.assert_allclose(bone_lengths(out.xy), np.broadcast_to(0.8 * lengths, (len(out), len(lengths))),
                               rtol=1e-4)
    # ... and the dropped root's (0, 0) does not drag the body: frame 12 sits between its neighbours.
    neck = JOINT_INDEX["Neck"]
    assert np.abs(out.xy[12, neck] - out.xy[[11, 13], neck].mean(axis=0)).max() < 5
    # A joint never seen has no position to aim at: the wrist beyond it moves with the shoulder.
    kp[:, elbow, 2] = 0.0
    never = PoseSequence(kp, 15.0, 640, 480)
    out = retarget(never, 0.8 * lengths)
    np.testing.assert_allclose(out.xy[:, wrist] - out.xy[:, shoulder], never.xy[:, wrist] - never.xy[:, shoulder],
                               atol=1e-3)


def test_target_lengths_are_medians_of_confident_frames_and_unseen_bones_keep_the_dances_length(standing):
    lengths = own_lengths(standing)
    target = dance(standing, lengths, frames=30)
    kp = target.keypoints.copy()
    kp[3, JOINT_INDEX["RWrist"]] = (600.0, 10.0, 0.01)  # a wild, unconfident detection
    kp[:, [JOINT_INDEX["LSmallToe"], JOINT_INDEX["RSmallToe"]], 2] = 0.0  # BlazePose has no small toes
    measured = target_bone_lengths(target.replace(kp))
    assert (measured[SMALL_TOE_BONES] == 0).all()
    known = [b for b in range(len(BODY25_LIMBS)) if b not in SMALL_TOE_BONES]
    np.testing.assert_allclose(measured[known], lengths[known], rtol=1e-4)
    source = dance(standing, 1.5 * lengths)
    out = retarget(source, measured)
    np.testing.assert_allclose(bone_lengths(out.xy)[:, SMALL_TOE_BONES], bone_lengths(source.xy)[:, SMALL_TOE_BONES],
                               rtol=1e-4)
    np.testing.assert_allclose(bone_lengths(out.xy)[:, known], np.broadcast_to(lengths[known], (len(out), len(known))),
                               rtol=1e-4)


def test_retarget_onto_then_normalisation_gives_the_target_its_own_arms(standing):
    # The target: 2x as large in its 1280x960 canvas, standing still; the dance: arms 1.8x too long, own canvas.
    target_lengths = 2.0 * own_lengths(standing)
    target = dance(2.0 * standing, target_lengths, legs_move=False, size=(1280, 960))
    stretched = own_lengths(standing)
    stretched[ARM_BONES] *= 1.8
    source = dance(standing, stretched, legs_move=False)
    moved = retarget_onto(source, target_bone_lengths(target))
    # Proportions change, size and place do not: the dance stays on its canvas at its body height.
    np.testing.assert_allclose(moved.xy[:, ROOT], source.xy[:, ROOT], atol=1e-3)
    assert body_height(target_bone_lengths(moved)) == pytest.approx(body_height(target_bone_lengths(source)), 1e-4)
    on_target = fit_normalization(moved, target).apply(moved)
    np.testing.assert_allclose(bone_lengths(on_target.xy)[:, ARM_BONES],
                               np.broadcast_to(target_lengths[ARM_BONES], (len(source), 4)), rtol=1e-3)
    np.testing.assert_allclose(directions(on_target.xy), directions(source.xy), atol=1e-5)


def test_lengths_of_the_wrong_shape_are_refused(standing):
    with pytest.raises(ValueError):
        retarget(dance(standing, own_lengths(standing), frames=4), np.ones(3))


def test_the_appearance_model_keeps_the_targets_bone_lengths(tiny_run, tiny_target):
    model = load_appearance_model(tiny_run, "cpu", optimize=False)
    np.testing.assert_allclose(model.bone_lengths, target_bone_lengths(PoseSequence.load(tiny_target[1])))
