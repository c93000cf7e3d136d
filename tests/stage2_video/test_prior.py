"""The warped prior: parts cut by the nearest bone, moved by exact transforms, retrieved by pose."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from dancesynth.core.skeleton import JOINT_INDEX as J
from stage2_video.masks import person_mask
from stage2_video.prior import (
    GROUPS,
    HAND_PARTS,
    NO_PART,
    OFF_MASK_COST,
    PARTS,
    TORSO,
    TORSO_CORNERS,
    FrameBank,
    PriorRenderer,
    Source,
    body_scale,
    bone_affine,
    fill_torso,
    off_mask_costs,
    part_labels,
    reference_lengths,
    similarity,
    warp_parts,
)

SIZE = 128


def standing_pose() -> np.ndarray:
    """A person facing the camera, arms a little away from the body, in a 128 x 128 image."""
    xy = {"Nose": (64, 22), "Neck": (64, 34), "RShoulder": (54, 35), "RElbow": (48, 50), "RWrist": (45, 64),
          "LShoulder": (74, 35), "LElbow": (80, 50), "LWrist": (83, 64), "MidHip": (64, 66), "RHip": (58, 66),
          "RKnee": (57, 86), "RAnkle": (57, 106), "LHip": (70, 66), "LKnee": (71, 86), "LAnkle": (71, 106),
          "REye": (62, 20), "LEye": (66, 20), "REar": (60, 21), "LEar": (68, 21), "LBigToe": (74, 110),
          "LHeel": (70, 109), "RBigToe": (54, 110), "RHeel": (58, 109)}
    kp = np.zeros((25, 3), np.float32)
    for name, (x, y) in xy.items():
        kp[J[name]] = (x, y, 1.0)
    return kp


def textured_person(kp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(``[H, W, 3]`` uint8 image: a smooth colour gradient, different everywhere; ``[H, W]`` uint8 mask)."""
    mask = person_mask(kp, SIZE, SIZE, 32.0, 0.0).astype(np.uint8) * 255
    y, x = np.mgrid[:SIZE, :SIZE]
    image = np.stack([2 * x, 2 * y, 255 - x - y], axis=2).clip(0, 255).astype(np.uint8)
    return image, mask


def source_of(image: np.ndarray, mask: np.ndarray, kp: np.ndarray) -> Source:
    labels = part_labels(mask, kp)
    filled, torso = fill_torso(image, labels, kp)
    return Source(image, filled, labels, torso, kp)


def moved(kp: np.ndarray, m: np.ndarray) -> np.ndarray:
    out = kp.copy()
    out[:, :2] = kp[:, :2] @ m[:, :2].T + m[:, 2]
    return out


def test_similarity_and_bone_affine_are_exact():
    angle, scale = np.deg2rad(25), 1.2
    m = np.array([[scale * np.cos(angle), -scale * np.sin(angle), 7.0], [scale * np.sin(angle), scale * np.cos(angle),
                                                                         -3.0]])
    points = np.random.default_rng(0).uniform(0, 100, (6, 2))
    assert np.allclose(similarity(points, points @ m[:, :2].T + m[:, 2]), m)
    # At a given scale: the least-squares rotation and translation (the head's, at the torso's scale).
    half = m.copy()
    half[:, :2] /= 2
    assert np.allclose(similarity(points, points @ m[:, :2].T + m[:, 2], scale=scale / 2)[:, :2], half[:, :2])
    a, b, a2, b2 = np.array([10.0, 10]), np.array([10.0, 30]), np.array([50.0, 50]), np.array([80.0, 50])
    affine = bone_affine(a, b, a2, b2, across=0.8)
    assert np.allclose(affine @ [*a, 1], a2) and np.allclose(affine @ [*b, 1], b2)
    # Across the bone the torso's scale: a point 5 px beside the source bone lands 4 px beside the target bone.
    assert np.allclose(affine @ [15.0, 10, 1], a2 - [0, 4])
    # A foreshortened source limb is not stretched past MAX_STRETCH times the torso's scale.
    assert np.allclose(bone_affine(a, b, a2, a2 + [200.0, 0], across=0.8) @ [*b, 1], a2 + [20 * 0.8 * 2.5, 0])


def test_a_body_moved_by_a_known_transform_lands_exactly_where_it_should():
    kp = standing_pose()
    image, mask = textured_person(kp)
    angle = np.deg2rad(12)
    m = np.array([[1.1 * np.cos(angle), -1.1 * np.sin(angle), 4.0], [1.1 * np.sin(angle), 1.1 * np.cos(angle), -6.0]])
    source = source_of(image, mask, kp)
    colour, alpha = warp_parts({g: source for g in GROUPS}, moved(kp, m), (SIZE, SIZE))
    expected_alpha = cv2.warpAffine(mask, m, (SIZE, SIZE), flags=cv2.INTER_LINEAR) / 255.0
    expected = cv2.warpAffine(image, m, (SIZE, SIZE), flags=cv2.INTER_LINEAR).astype(np.float32)
    inside = cv2.erode((expected_alpha > 0.99).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert inside.sum() > 500
    assert np.abs(alpha[inside] - 1).max() < 1e-3
    assert np.abs(colour[inside] - expected[inside]).max() <= 3  # every part moved by the same similarity
    outside = cv2.dilate((expected_alpha > 0).astype(np.uint8), np.ones((7, 7), np.uint8)) == 0
    assert alpha[outside].max() == 0


def test_a_torso_bending_towards_the_camera_leaves_the_head_its_size():
    """Everything above the hips squashed to 0.6 of its height (bending towards the camera): the legs keep the
    body's size, so the head keeps its own (sized by the torso's similarity, as before, it shrank)."""
    kp = standing_pose()
    image, mask = textured_person(kp)
    labels = part_labels(mask, kp)
    head = [i for i, part in enumerate(PARTS) if part.name == "head"][0]
    image[labels == head] = (255, 0, 0)
    bent = kp.copy()
    above_hips = bent[:, 1] < bent[J["MidHip"], 1]
    bent[above_hips, 1] = bent[J["MidHip"], 1] - (bent[J["MidHip"], 1] - bent[above_hips, 1]) * 0.6
    reference = reference_lengths(kp[None])
    assert body_scale(kp, reference) == pytest.approx(1.0)
    assert body_scale(bent, reference) == pytest.approx(1.0, abs=0.05)
    source = source_of(image, mask, kp)

    def head_area(reference: np.ndarray | None) -> int:
        colour, _ = warp_parts({g: source for g in GROUPS}, bent, (SIZE, SIZE), reference)
        return int(((colour[..., 0] > 150) & (colour[..., 1] < 60)).sum())

    own = int((labels == head).sum())
    assert head_area(reference) == pytest.approx(own, rel=0.1)
    assert head_area(None) < 0.75 * own


def warped_markers(joints: tuple[str, ...], radius: int, target: np.ndarray) -> np.ndarray:
    """Where red markers on ``joints`` of a grey standing person land when it is warped onto ``target``
    (``[SIZE, SIZE]`` bool)."""
    kp = standing_pose()
    image, mask = textured_person(kp)
    image[:] = (40, 40, 40)
    for joint in joints:
        cv2.circle(image, tuple(int(v) for v in kp[J[joint], :2]), radius, (255, 0, 0), -1)
    colour, _ = warp_parts({g: source_of(image, mask, kp) for g in GROUPS}, target, (SIZE, SIZE))
    return (colour[..., 0] > 150) & (colour[..., 1] < 60)


def test_a_forearm_turned_about_its_elbow_carries_its_hand_to_the_new_wrist():
    kp = standing_pose()
    wrist, elbow = kp[J["RWrist"], :2], kp[J["RElbow"], :2]
    target = kp.copy()
    target[J["RWrist"], :2] = elbow + (-(wrist - elbow)[1], (wrist - elbow)[0])  # the forearm turned 90 degrees
    red = warped_markers(("RWrist",), 2, target)
    ys, xs = np.nonzero(red)
    assert len(xs) and np.hypot(xs.mean() - target[J["RWrist"], 0], ys.mean() - target[J["RWrist"], 1]) < 1.5
    assert not red[int(wrist[1]), int(wrist[0])]  # nothing of the hand stays behind


def test_a_head_tilted_about_the_neck_carries_its_eyes_to_the_new_eyes():
    kp = standing_pose()
    neck = kp[J["Neck"], :2]
    angle = np.deg2rad(30)
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    target = kp.copy()
    for name in ("Nose", "REye", "LEye", "REar", "LEar"):
        target[J[name], :2] = neck + turn @ (kp[J[name], :2] - neck)
    red = warped_markers(("REye", "LEye"), 1, target)
    for eye in ("REye", "LEye"):
        x, y = target[J[eye], :2]
        assert red[int(y) - 2:int(y) + 3, int(x) - 2:int(x) + 3].any(), f"no marker within 2 px of the {eye}"


def test_a_bent_knee_leaves_the_foot_flat_where_its_toes_are():
    kp = standing_pose()
    target = kp.copy()
    target[J["LKnee"], 0] += 8  # the knee out to the side: thigh and shin turn, ankle, toe and heel stay
    ys, xs = np.nonzero(warped_markers(("LBigToe",), 1, target))
    toe = kp[J["LBigToe"], :2]
    assert len(xs) and np.hypot(xs.mean() - toe[0], ys.mean() - toe[1]) < 1.5


def test_a_hand_on_the_hip_belongs_to_its_arm_and_the_torso_behind_an_arm_is_filled():
    kp = standing_pose()
    kp[J["RElbow"], :2] = (46, 50)
    kp[J["RWrist"], :2] = (58, 60)  # the right hand rests on the body, inside the torso
    image, mask = textured_person(kp)
    labels = part_labels(mask, kp)
    hand = PARTS.index(next(p for p in PARTS if p.name == "right hand"))
    tip = kp[J["RWrist"], :2] + 0.3 * (kp[J["RWrist"], :2] - kp[J["RElbow"], :2])
    assert labels[int(tip[1]), int(tip[0])] == hand
    assert labels[0, 0] == NO_PART and labels[int(kp[J["Neck"], 1]) + 8, 64] == TORSO
    image[labels != TORSO] = (255, 0, 0)  # limbs red, torso the gradient
    filled, region = fill_torso(image, labels, kp)
    covered = region & (labels != TORSO)
    assert covered.sum() > 20  # where the forearm lay across the torso
    assert not (filled[covered] == (255, 0, 0)).all(axis=1).any()  # filled from the torso, not the arm


def test_a_piece_of_a_part_cut_off_from_its_bone_stays_behind_when_the_part_moves():
    # A fold of trousers under the hand, parted from it by a dark crease and joined to the body through the thigh:
    # nearest the hand's line, but apart from the hand. Labelled the hand, it swung away with a moved arm as a
    # sliver beside the body.
    kp = standing_pose()
    image, mask = textured_person(kp)
    hand = PARTS.index(next(p for p in PARTS if p.name == "right hand"))
    mask[76:78, :51] = 0
    labels = part_labels(mask, kp)
    assert labels[70, 42] == hand and (labels[79:81, 40:47] != hand).all()
    raised = kp.copy()
    raised[J["RElbow"], :2], raised[J["RWrist"], :2] = (42, 30), (36, 16)
    _, alpha = warp_parts({g: source_of(image, mask, kp) for g in GROUPS}, raised, (SIZE, SIZE))
    count, _ = cv2.connectedComponents((alpha > 0.5).astype(np.uint8), connectivity=8)
    assert count == 2, "nothing of the person floats apart from the body"


def test_the_torso_takes_no_arm_pixels_beyond_its_shoulders():
    # Arm pixels the torso fills in stay between shoulders and hips: beyond them, moved under an arm at another
    # angle, they stood out as square pads at the shoulders.
    kp = standing_pose()
    image, mask = textured_person(kp)
    labels = part_labels(mask, kp)
    _, region = fill_torso(image, labels, kp)
    quad = np.zeros(mask.shape, np.uint8)
    cv2.fillConvexPoly(quad, np.round(kp[list(TORSO_CORNERS), :2]).astype(np.int32), 1)
    taken = region & (labels != TORSO)
    assert taken.any() and not (taken & (quad == 0)).any()


def test_a_glove_the_pose_put_elsewhere_takes_the_colour_of_the_part_it_lies_on():
    # A dark suit with red gloves; in the last frame the pose misread a hand, so a glove lies on the left thigh.
    kp = standing_pose()
    _, mask = textured_person(kp)
    labels = part_labels(mask, kp)
    image = np.zeros((SIZE, SIZE, 3), np.uint8)
    image[labels != NO_PART] = (30, 30, 40)
    image[np.isin(labels, HAND_PARTS)] = (200, 20, 20)
    misread = image.copy()
    glove = np.zeros((SIZE, SIZE), bool)
    cv2.circle(glove.view(np.uint8), (71, 78), 3, 1, -1)
    assert (labels[glove] == PARTS.index(next(p for p in PARTS if p.name == "left thigh"))).all()
    misread[glove] = (200, 20, 20)
    frames = np.stack([image] * 40 + [misread])
    bank = FrameBank(frames, np.stack([mask] * 41), np.stack([kp] * 41), np.arange(41))
    cut = bank.source(40).image
    assert (cut[glove] == (30, 30, 40)).all()
    assert (cut[np.isin(labels, HAND_PARTS)] == (200, 20, 20)).all()  # the hands themselves keep their gloves
    assert (bank.source(0).image == image).all()


def _bank(poses: np.ndarray) -> FrameBank:
    frames = np.zeros((len(poses), 8, 8, 3), np.uint8)
    return FrameBank(frames, np.zeros((len(poses), 8, 8), np.uint8), poses, np.arange(len(poses)))


def arms_out(kp: np.ndarray) -> np.ndarray:
    """``kp`` with both arms held out sideways, clear of the body."""
    out = kp.copy()
    for name, xy in (("RElbow", (40, 38)), ("RWrist", (24, 38)), ("LElbow", (88, 38)), ("LWrist", (104, 38))):
        out[J[name], :2] = xy
    return out


def test_retrieval_ignores_position_and_scale_and_never_returns_excluded_frames():
    rng = np.random.default_rng(1)
    base = arms_out(standing_pose())
    poses = np.repeat(base[None], 60, axis=0)
    poses[:, :, :2] += rng.normal(0, 4, (60, 25, 2))
    bank = _bank(poses)
    # The same pose somewhere else, larger: the same frame for every group.
    query = poses[17].copy()
    query[:, :2] = query[:, :2] * 1.7 + (30, -12)
    assert set(bank.retrieve(query).values()) == {17}
    previous = None
    for t in range(60):
        window = (t - 5, t + 6)
        choice = bank.retrieve(poses[t], window, previous)
        assert all(not window[0] <= f < window[1] for f in choice.values()), (t, choice)
        # The median prior's candidates: retrieval's choice first, then other frames, none excluded.
        chosen = bank.choices(poses[t], 3, window, previous)
        assert chosen[0] == choice
        for group in GROUPS:
            frames = [c[group] for c in chosen]
            assert len(set(frames)) == 3 and not any(window[0] <= f < window[1] for f in frames)
        previous = choice
    # A bank shorter than the window keeps its farthest frames rather than failing.
    assert set(bank.retrieve(poses[30], (-100, 100)).values()) <= {0, 59}


def test_among_like_poses_retrieval_takes_the_frame_where_the_person_stood_nearest():
    pose = arms_out(standing_pose())
    poses = np.repeat(pose[None], 2, axis=0)
    scene = poses.copy()
    scene[1, :, 0] += 300  # frame 1: the same pose, far to the right in the scene (another light)
    frames = np.zeros((2, 8, 8, 3), np.uint8)
    bank = FrameBank(frames, np.zeros((2, 8, 8), np.uint8), poses, np.arange(2), scene=scene)
    there = pose.copy()
    there[:, 0] += 280
    assert set(bank.retrieve(pose, scene=pose).values()) == {0}
    assert set(bank.retrieve(pose, scene=there).values()) == {1}
    # A clearly better pose still wins over a place a torso length nearer (32 pixels).
    bent, near = poses.copy(), scene.copy()
    bent[1] = near[1] = standing_pose()
    near[1, :, 0] += 32
    bank = FrameBank(frames, np.zeros((2, 8, 8), np.uint8), bent, np.arange(2), scene=near)
    there = pose.copy()
    there[:, 0] += 32
    assert bank.retrieve(pose, scene=there)["right arm"] == 0


def test_retrieval_prefers_frames_whose_hands_cover_no_part():
    open_arms = arms_out(standing_pose())
    hand_on_face = open_arms.copy()
    hand_on_face[J["RElbow"], :2], hand_on_face[J["RWrist"], :2] = (52, 34), (60, 24)
    nearly = open_arms.copy()
    nearly[:, :2] += np.random.default_rng(2).normal(0, 1.5, (25, 2))  # a little less like the query
    bank = _bank(np.stack([hand_on_face, nearly]))
    query = hand_on_face.copy()
    query[[J["RElbow"], J["RWrist"]]] = open_arms[[J["RElbow"], J["RWrist"]]]
    # The head and torso come from the frame with the hand away from the face, not from the one whose face the
    # hand would have cut out; the right arm from the frame whose arm matches.
    assert bank.retrieve(query)["core"] == 1


@pytest.mark.parametrize("elbow, query_wrist, on_part, clear, query_on_part", [
    # The hand raised beside the head: cut from a frame with the hand on the face, the arm carries the face along.
    ((48, 26), (54, 12), (60, 20), (42, 12), (61, 21)),
    # The hand hanging beside the thigh: cut from a frame with the hand on it, the hand carries a wedge of trousers.
    ((48, 50), (50, 70), (55, 72), (44, 66), (55, 72)),
], ids=["face", "thigh"])
def test_an_arm_clear_of_a_part_is_not_taken_from_a_frame_whose_hand_lies_on_it(elbow, query_wrist, on_part, clear,
                                                                                 query_on_part):
    query = standing_pose()
    query[J["RElbow"], :2], query[J["RWrist"], :2] = elbow, query_wrist
    lying, away = query.copy(), query.copy()
    lying[J["RWrist"], :2] = on_part  # nearer the query's forearm than the other, but the hand on the part
    away[J["RWrist"], :2] = clear
    bank = _bank(np.stack([lying, away]))
    assert bank.retrieve(query)["right arm"] == 1
    query[J["RWrist"], :2] = query_on_part  # a hand on the part is still taken from a frame that shows one
    assert bank.retrieve(query)["right arm"] == 0


@pytest.mark.parametrize("facing_away", [False, True])
def test_retrieval_keeps_left_and_right(facing_away):
    front = standing_pose()
    back = front.copy()
    for right, left in (("RShoulder", "LShoulder"), ("RElbow", "LElbow"), ("RWrist", "LWrist"), ("RHip", "LHip"),
                        ("RKnee", "LKnee"), ("RAnkle", "LAnkle")):
        back[J[right]], back[J[left]] = front[J[left]].copy(), front[J[right]].copy()
    back[[J["REye"], J["LEye"], J["Nose"]], 2] = 0.0  # seen from behind: no face
    bank = _bank(np.stack([front, back]))
    assert set(bank.retrieve(back if facing_away else front).values()) == {int(facing_away)}


def test_the_head_and_torso_come_from_a_frame_whose_head_turns_the_same_way():
    front = standing_pose()
    turned = front.copy()  # eyes and ears 2 px to the image's left: the head turns, the body does not
    turned[[J["REye"], J["LEye"], J["REar"], J["LEar"]], 0] -= 2.0
    # A turned head on shoulders a little higher than the pose's, and the pose's body with a frontal head: in torso
    # lengths the shoulders differ more than the face, in head lengths the face more.
    higher = turned.copy()
    higher[[J["RShoulder"], J["LShoulder"]], 1] -= 2.5
    bank = _bank(np.stack([front, higher]))
    assert bank.retrieve(turned)["core"] == 1
    assert bank.retrieve(front)["core"] == 0


def test_the_torso_comes_from_a_frame_whose_upper_arms_lie_like_the_poses():
    hanging = standing_pose()
    # The same torso with the arms held out, and the pose's hanging arms on shoulders a little higher: a torso cut
    # from the first would carry the start of the held-out arms to the shoulders.
    held_out = arms_out(hanging)
    higher = hanging.copy()
    higher[[J["RShoulder"], J["LShoulder"]], 1] -= 1.5
    bank = _bank(np.stack([held_out, higher]))
    assert bank.retrieve(hanging)["core"] == 1
    assert bank.retrieve(held_out)["core"] == 0


def test_the_median_prior_drops_a_part_that_only_one_of_its_frames_gets_wrong():
    kp = standing_pose()
    image, mask = textured_person(kp)
    wrong = image.copy()
    wrong[mask > 0] = (0, 0, 255)  # the nearest frame's person is blue: a misread frame
    poses = np.repeat(kp[None], 3, axis=0)
    poses[1:, :, :2] += np.random.default_rng(3).normal(0, 0.3, (2, 25, 2))  # the others a little farther
    frames = np.stack([wrong, image, image])
    masks = np.repeat(mask[None], 3, axis=0)
    inside = cv2.erode(mask, np.ones((7, 7), np.uint8)) > 0
    plate = np.zeros((SIZE, SIZE, 3), np.uint8)
    for candidates, blue_share in ((1, 1.0), (3, 0.0)):
        bank = FrameBank(frames, masks, poses, np.arange(3), candidates=candidates)
        prior = PriorRenderer(bank)(kp, plate)
        blue = (prior[..., 2] == 255) & (prior[..., 0] == 0) & (prior[..., 1] == 0)
        assert blue[inside].mean() == pytest.approx(blue_share, abs=0.02)
        assert (prior[..., 3][inside] == 255).all()
    with pytest.raises(ValueError, match="odd"):
        FrameBank(frames, masks, poses, np.arange(3), candidates=2)


def test_a_frame_whose_mask_spreads_over_the_scene_is_never_retrieved():
    kp = standing_pose()
    image, mask = textured_person(kp)
    spilt = mask.copy()
    spilt[:, 96:] = 255  # a failed segmentation: a band of scene beside the person taken for them
    poses = np.repeat(kp[None], 2, axis=0)
    poses[1, :, :2] += 0.5  # frame 1 a little farther from the query than frame 0
    frames, plate = np.stack([image, image]), np.zeros((SIZE, SIZE, 3), np.uint8)
    bank = FrameBank(frames, np.stack([spilt, mask]), poses, np.arange(2))
    assert set(bank.retrieve(kp).values()) == {1}
    assert bank.retrieve(kp, exclude=(1, 2)) == dict.fromkeys(GROUPS, 0)  # the only frame allowed: used all the same
    clean = FrameBank(frames, np.stack([mask, mask]), poses, np.arange(2))
    assert set(clean.retrieve(kp).values()) == {0}
    assert (PriorRenderer(bank)(kp, plate)[:, 100:, 3] == 0).all()


def test_parts_the_video_hides_in_most_frames_are_named():
    # A person standing behind a table that hides the hips and thighs in three frames of four.
    kp = standing_pose()
    image, mask = textured_person(kp)
    behind = mask.copy()
    behind[62:90] = 0
    frames = np.stack([image] * 4)
    bank = FrameBank(frames, np.stack([behind, behind, behind, mask]), np.stack([kp] * 4), np.arange(4))
    assert bank.hidden_parts() == ["hips", "right thigh", "left thigh"]
    assert FrameBank(frames, np.stack([mask] * 4), np.stack([kp] * 4), np.arange(4)).hidden_parts() == []
    # Filmed from the waist up: the pose has no legs.
    upper = kp.copy()
    upper[[J[n] for n in ("RKnee", "RAnkle", "LKnee", "LAnkle", "RBigToe", "LBigToe", "RHeel", "LHeel")], 2] = 0.0
    bank = FrameBank(frames, np.stack([mask] * 4), np.stack([upper] * 4), np.arange(4))
    assert bank.hidden_parts() == ["right thigh", "right shin", "left thigh", "left shin"]


def test_a_limb_is_not_taken_from_a_frame_whose_pose_puts_it_off_the_person():
    # Two frames alike by pose (retrieval ignores position, so they tie and the first wins); frame 0's mask lacks
    # the left arm where its pose has it (a misread limb, as BlazePose reads a dark forearm against a dark suit).
    kp = standing_pose()
    image, mask = textured_person(kp)
    armless = mask.copy()
    armless[:, 76:] = 0
    poses = np.stack([kp, kp + np.float32([0.5, 0.5, 0.0])])
    bank = FrameBank(np.stack([image, image]), np.stack([armless, mask]), poses, np.arange(2))
    chosen = bank.retrieve(kp)
    assert chosen["left arm"] == 1
    assert chosen["right arm"] == chosen["right leg"] == chosen["left leg"] == chosen["core"] == 0
    assert (off_mask_costs(bank.masks, poses, np.arange(2))["left arm"] == [OFF_MASK_COST, 0.0]).all()


def test_a_hand_hanging_beside_the_thigh_leaves_the_thigh_behind_when_the_arm_rises():
    # A thin left arm hangs against a wide hip and thigh (one mass, as the dancer's dark suit). Raised, the arm
    # must carry its own width, not a slab of the thigh hanging below it.
    kp = standing_pose()
    kp[J["LElbow"], :2], kp[J["LWrist"], :2] = (80, 50), (80, 65)
    image, _ = textured_person(kp)
    mask = np.zeros((SIZE, SIZE), np.uint8)
    point = {name: tuple(int(v) for v in kp[J[name], :2]) for name in J if kp[J[name], 2] > 0}
    cv2.fillPoly(mask, [np.array([point[n] for n in ("RShoulder", "LShoulder", "LHip", "RHip")])], 255)
    cv2.circle(mask, point["Nose"], 7, 255, -1)
    for a, b, width in (("Neck", "Nose", 6), ("RHip", "RKnee", 18), ("LHip", "LKnee", 18), ("RKnee", "RAnkle", 10),
                        ("LKnee", "LAnkle", 10), ("RShoulder", "RElbow", 4), ("RElbow", "RWrist", 4),
                        ("LShoulder", "LElbow", 4), ("LElbow", "LWrist", 4)):
        cv2.line(mask, point[a], point[b], 255, width)
    raised = kp.copy()
    raised[J["LElbow"], :2], raised[J["LWrist"], :2] = (92, 35), (108, 35)
    _, alpha = warp_parts({g: source_of(image, mask, kp) for g in GROUPS}, raised, (SIZE, SIZE))
    torso = float(np.linalg.norm(kp[J["Neck"], :2] - kp[J["MidHip"], :2]))
    y, x = np.mgrid[:SIZE, :SIZE]
    beside = x > kp[J["LShoulder"], 0] + 0.25 * torso  # the raised arm's side, clear of the torso
    assert (alpha[beside & (np.abs(y - 35) <= 2)] > 0.5).sum() > 0  # the arm is there
    assert (alpha[beside & (y > 35 + 0.25 * torso)] > 0.5).sum() == 0  # and nothing hangs from it
