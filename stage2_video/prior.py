"""The warped prior: the target person's own pixels moved onto a new pose, body part by body part.

A generator that must learn a person from scratch in minutes of CPU training draws a ghost. Methods that make a
recognisable person from little data start from the person's own pixels (Balakrishnan et al. CVPR 2018, part-wise
warping; Siarohin et al. CVPR 2018; few-shot vid2vid's warped reference; Efros et al. 2003's nearest-neighbour
retrieval). Here, for every pose to render:

1. **Retrieval** (:class:`FrameBank`): the training frames whose pose is nearest by a descriptor that ignores
   position and scale (each bone's vector in torso lengths, so direction and foreshortening count, plus which face
   points are visible and where they lie around the nose in head lengths: which way the head turns). Each group of
   parts (head and torso, each arm, each leg) takes its own nearest frame, with the bones that face the camera
   (shoulders, hips, face) and the head's turn in every group's cost so no part comes from a frame facing the other
   way, and frames whose hands lie on the group's parts costing more (an arm too, when its hand lies on the head,
   torso or a leg where the pose's does not: it would carry their pixels away), as do frames whose pose puts the
   group's limb off the person's mask (a misread limb: cut along it, the part holds the backdrop). A choice is
   kept from frame to frame while it stays nearly as good (no flicker), and frames within ``exclude`` of the frame
   being learnt are never returned (the network must learn to repair a warp, not to copy its input), nor frames
   whose person mask spreads far beyond the body (a failed segmentation, :data:`MASK_LEAK_LIMIT`).
2. **Parts** (:func:`part_labels`): the source frame's person mask (:mod:`stage2_video.masks`) is split into head,
   torso, upper arms, forearms, hands, thighs, shins and feet by the nearest drawn bone (a hand belongs to
   its arm even where it rests on the torso or a thigh, though a forearm or hand keeps only a narrow band where
   the torso or a leg reaches too, so a slab of hip does not swing away with it); a piece of a part's region apart
   from the pixels its bone is drawn on (trousers beside a hand that rests on a thigh) goes to the next nearest
   part, so it does not swing away with the part; torso pixels hidden by an arm are filled in from around them.
   Pixels outside the hands coloured like the bank's hands and unlike their own part (a glove the pose put
   elsewhere) take the colour of the part around them (:func:`clean_strays`).
3. **Warping** (:func:`warp_parts`): each pose's size is measured by its longest bones against the bank's
   (:func:`body_scale`: foreshortening only shortens a bone), and the ratio of the two sizes scales every part.
   The torso is stretched along its spine (neck to mid-hip) onto the target's and scaled by that ratio across it;
   each limb part by the affine that takes its source bone onto the target
   bone (stretched along the bone, the ratio across it); head and feet by the least-squares rotation and
   translation of their points (face and neck; ankle, toes and heel), hands by a similarity about the wrist, all
   at the ratio. Parts are
   painted back to front (torso, legs, head, arms, hands), giving an RGB + alpha image over the plate crop: the
   generator's "warped prior" (or the per-pixel median of several retrieved frames' warps, :class:`PriorRenderer`).

Everything is in the pixels of a bank image (the model's framing at ``scale`` times its resolution).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections import OrderedDict
from dataclasses import dataclass

import cv2
import numpy as np

from dancesynth.core.motion import bone_lengths
from dancesynth.core.skeleton import BODY25_LIMBS, JOINT_INDEX, NECK, ROOT
from stage2_video.framing import MIN_CONFIDENCE, Framing, VideoFraming

J = JOINT_INDEX
# Bones compared by retrieval, as (parent, child) joints; their vectors are measured in torso lengths.
DESCRIPTOR_BONES: tuple[tuple[int, int], ...] = (
    (J["Neck"], J["Nose"]), (J["Neck"], J["RShoulder"]), (J["Neck"], J["LShoulder"]), (J["Neck"], J["MidHip"]),
    (J["MidHip"], J["RHip"]), (J["MidHip"], J["LHip"]),
    (J["RShoulder"], J["RElbow"]), (J["RElbow"], J["RWrist"]), (J["LShoulder"], J["LElbow"]),
    (J["LElbow"], J["LWrist"]), (J["RHip"], J["RKnee"]), (J["RKnee"], J["RAnkle"]), (J["LHip"], J["LKnee"]),
    (J["LKnee"], J["LAnkle"]), (J["Nose"], J["REye"]), (J["Nose"], J["LEye"]),
)
# Face points whose visibility tells front, back and profile views apart.
FACE_POINTS = (J["REye"], J["LEye"], J["REar"], J["LEar"])
# The bones every group's retrieval cost includes: the ones that show which way the person faces.
FACING_BONES = (0, 1, 2, 4, 5, 14, 15)
# A bone present in the pose to render but absent in a bank frame costs this (squared torso lengths).
MISSING_COST = 1.0
# Weight of a face point seen in one pose and not the other.
FACE_COST = 0.3
# Weight of the face points' offsets from the nose (head lengths, squared) in every group's cost: in torso lengths
# they are too small to tell a turned head (and the body turning with it) from a frontal one.
HEAD_TURN_COST = 1.0
# Weight of the upper arms (DESCRIPTOR_BONES 6 and 8, shoulder to elbow) in the head and torso's cost: the torso's
# region holds where each upper arm starts, so a torso cut from a frame with the arms held out brings dark pads
# along to the shoulders of a pose whose arms hang.
TORSO_ARM_COST = 0.3
UPPER_ARM_BONES = (6, 8)
# A frame chosen for the previous pose is kept while its cost is within this of the best (squared torso lengths).
HYSTERESIS = 0.15
# Weight of the distance between where the person stands in the scene (mid-hips, canvas pixels) in a bank frame and
# in the pose to render, squared, in the rendered pose's torso lengths: the light on a person changes across a scene
# (sports2d: backlit with the sun behind him on the box, in sunlight on the grass), and by pose alone the frames on
# the box served the grass too, a pale grey ghost with the sun's flare. Chosen on the training range (docs/methods).
PLACE_COST = 0.2
# Retrieval cost of a bank frame whose forearm or hand lies on a group's parts (it would cover them), per point,
# at full overlap; and how near (torso lengths) to a group's bones a point starts to count: face and torso centre,
# legs.
OCCLUSION_COST = 1.0
OCCLUSION_REACH = {"core": 0.3, "right leg": 0.2, "left leg": 0.2}
OCCLUDED_BONES = {"core": ((J["Neck"], J["Nose"]), (J["Neck"], J["MidHip"])),
                  "right leg": ((J["RHip"], J["RKnee"]), (J["RKnee"], J["RAnkle"])),
                  "left leg": ((J["LHip"], J["LKnee"]), (J["LKnee"], J["LAnkle"]))}
# Retrieval cost of a bank frame whose pose puts a group's limb (or the spine) wholly off the person's mask, in
# proportion to the share off it: BlazePose misplaces a limb (the dancer's dark forearm against her suit, an arm
# held out read at the hip), and cut along that bone the part holds the backdrop or another part. Chosen on the
# training range (docs/methods/warped_prior.md).
OFF_MASK_COST = 2.0
# The person's colours per part are counted in bins of this many levels a channel, over this many bank frames.
COLOUR_LEVELS = 8
COLOUR_FRAMES = 128
# A pixel outside the hands whose colour is this many times likelier in a hand than in its own part is a hand the
# pose put elsewhere (a glove at the hip labelled thigh, 200-1400 times); the dancer's gloves, not sports2d's light
# on his legs (docs/methods/warped_prior.md).
STRAY_RATIO = 100.0
# A bank frame whose person mask lies beyond every part's reach over more than this share of its pixels is a failed
# segmentation (sports2d's backlit flip: sunlit leaves beside the body, 27-54 %; the dancer's frames at most 8 %):
# its parts carry pieces of the scene along, so retrieval passes it over.
MASK_LEAK_LIMIT = 0.2
# The body as a user names it, by the bones that show each part. A part whose bones' middles lie on the person's
# mask in fewer than SEEN_SHARE of the bank's frames is hidden in the target video, and a dance shows the background
# where its poses need it (a pianist's hips behind his keyboard: 17-45 % of frames; every bone of the dancer and of
# sports2d's man: 85 % or more).
SEEN_PARTS: dict[str, tuple[tuple[int, int], ...]] = {
    "torso": ((J["Neck"], J["MidHip"]),), "shoulders": ((J["Neck"], J["RShoulder"]), (J["Neck"], J["LShoulder"])),
    "right upper arm": ((J["RShoulder"], J["RElbow"]),), "right forearm": ((J["RElbow"], J["RWrist"]),),
    "left upper arm": ((J["LShoulder"], J["LElbow"]),), "left forearm": ((J["LElbow"], J["LWrist"]),),
    "hips": ((J["MidHip"], J["RHip"]), (J["MidHip"], J["LHip"])), "right thigh": ((J["RHip"], J["RKnee"]),),
    "right shin": ((J["RKnee"], J["RAnkle"]),), "left thigh": ((J["LHip"], J["LKnee"]),),
    "left shin": ((J["LKnee"], J["LAnkle"]),),
}
SEEN_SHARE = 0.5
# A part whose bones the poses have in fewer than this share of the bank's frames is outside the picture (a video
# from the waist up); a side view's far arm, hidden behind the body, is still posed in half of sports2d's frames.
MIN_POSED_SHARE = 0.1


@dataclass(frozen=True)
class Part:
    """One body part moved as a whole.

    Attributes:
        name: what it is.
        lines: joint pairs drawn to decide which pixels belong to it (nearest drawn part wins).
        bone: the joints whose move carries the part (None: the torso, moved by the similarity of its joints).
        rigid: moved by a similarity about ``bone``'s child joint, turned with the bone and scaled like the torso
            (head, hands: they keep their shape); else stretched along the bone onto the target bone (limbs).
        extend: a line past ``bone``'s child joint, in torso lengths along the bone (the hand), or 0.
        reach: how far (torso lengths) from its lines a person pixel may lie and still belong to it.
        group: the retrieval group it is taken from.
        bias: torso lengths added to its distance when parts compete for a pixel: torso and legs yield to the
            arms, hands and head in front of them (an arm across the body, a hand on a hip or a thigh); the face
            and a hand near it go by distance alone.
        fit: for a rigid part, joints whose least-squares rotation and translation between the poses move it (at
            least ``MIN_FIT_JOINTS`` seen in both; fewer: turned with ``bone``), scaled like the torso.
        keep: torso lengths from its lines beyond which it yields a pixel to any part without such a limit that
            reaches it: a forearm or hand hanging beside the body would otherwise take a slab of the hip or thigh
            along (a dark flap swinging with the arm in a dance), since those yield to it by their ``bias``.
    """

    name: str
    lines: tuple[tuple[int, int], ...]
    bone: tuple[int, int] | None
    rigid: bool
    extend: float
    reach: float
    group: str
    bias: float = 0.0
    fit: tuple[int, ...] = ()
    keep: float = math.inf


_R_FOREARM, _L_FOREARM = (J["RElbow"], J["RWrist"]), (J["LElbow"], J["LWrist"])
# Forearms and hands keep pixels other parts reach within this many torso lengths of their lines (Part.keep; a
# forearm is about 0.16 wide). Chosen by the demo's dance against the synthetic truth and by eye on the dancer's
# dance (docs/methods/warped_prior.md).
ARM_KEEP = 0.1
# Back to front: the order parts are painted in.
PARTS: tuple[Part, ...] = (
    Part("torso", ((J["Neck"], J["MidHip"]),), None, False, 0.0, 0.25, "core", bias=0.15),
    Part("right thigh", ((J["RHip"], J["RKnee"]),), (J["RHip"], J["RKnee"]), False, 0.0, 0.3, "right leg", bias=0.15),
    Part("left thigh", ((J["LHip"], J["LKnee"]),), (J["LHip"], J["LKnee"]), False, 0.0, 0.3, "left leg", bias=0.15),
    Part("right shin", ((J["RKnee"], J["RAnkle"]),), (J["RKnee"], J["RAnkle"]), False, 0.0, 0.3, "right leg",
         bias=0.15),
    Part("left shin", ((J["LKnee"], J["LAnkle"]),), (J["LKnee"], J["LAnkle"]), False, 0.0, 0.3, "left leg", bias=0.15),
    Part("right foot", ((J["RAnkle"], J["RBigToe"]), (J["RAnkle"], J["RHeel"]), (J["RAnkle"], J["RSmallToe"])),
         (J["RKnee"], J["RAnkle"]), True, 0.0, 0.3, "right leg", bias=0.15,
         fit=(J["RAnkle"], J["RBigToe"], J["RHeel"], J["RSmallToe"])),
    Part("left foot", ((J["LAnkle"], J["LBigToe"]), (J["LAnkle"], J["LHeel"]), (J["LAnkle"], J["LSmallToe"])),
         (J["LKnee"], J["LAnkle"]), True, 0.0, 0.3, "left leg", bias=0.15,
         fit=(J["LAnkle"], J["LBigToe"], J["LHeel"], J["LSmallToe"])),
    Part("head", ((J["Neck"], J["Nose"]), (J["Nose"], J["REye"]), (J["Nose"], J["LEye"]), (J["REye"], J["REar"]),
                  (J["LEye"], J["LEar"])), (J["Neck"], J["Nose"]), True, 0.0, 0.5, "core",
         fit=(J["Neck"], J["Nose"], J["REye"], J["LEye"], J["REar"], J["LEar"])),
    Part("right upper arm", ((J["RShoulder"], J["RElbow"]),), (J["RShoulder"], J["RElbow"]), False, 0.0, 0.25,
         "right arm"),
    Part("left upper arm", ((J["LShoulder"], J["LElbow"]),), (J["LShoulder"], J["LElbow"]), False, 0.0, 0.25,
         "left arm"),
    Part("right forearm", (_R_FOREARM,), _R_FOREARM, False, 0.0, 0.25, "right arm", keep=ARM_KEEP),
    Part("left forearm", (_L_FOREARM,), _L_FOREARM, False, 0.0, 0.25, "left arm", keep=ARM_KEEP),
    Part("right hand", (), _R_FOREARM, True, 0.35, 0.25, "right arm", keep=ARM_KEEP),
    Part("left hand", (), _L_FOREARM, True, 0.35, 0.25, "left arm", keep=ARM_KEEP),
)
TORSO = 0
HAND_PARTS = tuple(i for i, part in enumerate(PARTS) if part.name.endswith(" hand"))
# Forearms and hands: they keep only pixels near their lines where other parts reach too (Part.keep).
ARM_ENDS = tuple(i for i, part in enumerate(PARTS) if part.keep < math.inf)
_UNLIMITED = [i for i in range(len(PARTS)) if i not in ARM_ENDS]
# The torso quadrilateral: its pixels are at distance 0 from the torso.
TORSO_CORNERS = (J["RShoulder"], J["LShoulder"], J["LHip"], J["RHip"])
TORSO_JOINTS = (J["Neck"], J["RShoulder"], J["LShoulder"], J["MidHip"], J["RHip"], J["LHip"])
# Indices of DESCRIPTOR_BONES per retrieval group (besides FACING_BONES).
GROUP_BONES: dict[str, tuple[int, ...]] = {
    "core": (0, 1, 2, 3, 4, 5), "right arm": (6, 7), "left arm": (8, 9), "right leg": (10, 11), "left leg": (12, 13),
}
GROUPS = tuple(GROUP_BONES)
# The bones a group's parts are cut along (its bones besides the facing ones).
GROUP_OWN_BONES = {group: tuple(b for b in bones if b not in FACING_BONES) for group, bones in GROUP_BONES.items()}
# A limb (or the torso, along its spine) may stretch to at most this factor of the size ratio across it (a
# foreshortened source limb).
MAX_STRETCH = 2.5
# The body's bones by which a pose's size is measured (BODY25_LIMBS up to neck-nose: torso, shoulders, arms, hips,
# legs, neck); the face's and feet's are too short to tell a size by.
SCALE_BONES = np.arange(BODY25_LIMBS.index((NECK, J["Nose"])) + 1)
# A bone's reference length is this percentile of its lengths in the bank: its length across the image.
REFERENCE_PERCENTILE = 90
# A pose's size is its bones' (length / reference) ratios ranked from the largest, this one taken (1-based), when at
# least SCALE_MIN_BONES are seen: a bone pointing at the camera only shortens, and one misplaced joint only
# lengthens one or two.
SCALE_RANK = 2
SCALE_MIN_BONES = 3
# A rigid part is placed by its own features (the face's points) when at least this many are seen in both poses.
MIN_FIT_JOINTS = 3
# Each part's region grows by this many pixels into its neighbours', so moved parts overlap instead of leaving a seam.
OVERLAP_PIXELS = 2
NO_PART = 255


def scaled_framing(framing: VideoFraming, scale: int) -> VideoFraming:
    """The same crop box(es) resized to ``scale`` times the model image (bank and output pixels)."""
    return dataclasses.replace(framing, out_width=framing.out_width * scale, out_height=framing.out_height * scale)


def reference_lengths(keypoints: np.ndarray) -> np.ndarray:
    """``[len(SCALE_BONES)]`` each body bone's :data:`REFERENCE_PERCENTILE` length over ``[T, 25, 3]`` poses
    (pixels; NaN where never seen): the bone's length when it lies across the image, not towards the camera."""
    lengths = _scale_bone_lengths(keypoints)
    seen = np.isfinite(lengths).any(0)
    out = np.full(lengths.shape[-1], np.nan)
    out[seen] = np.nanpercentile(lengths[:, seen], REFERENCE_PERCENTILE, axis=0)
    return out


def _scale_bone_lengths(keypoints: np.ndarray) -> np.ndarray:
    """``[..., len(SCALE_BONES)]`` lengths (pixels; NaN where a joint is absent) of ``[..., 25, 3]`` poses."""
    kp = np.asarray(keypoints, np.float64)
    parent, child = np.array(BODY25_LIMBS)[SCALE_BONES].T
    seen = (kp[..., parent, 2] >= MIN_CONFIDENCE) & (kp[..., child, 2] >= MIN_CONFIDENCE)
    return np.where(seen, bone_lengths(kp[..., :2])[..., SCALE_BONES], np.nan)


def body_scale(keypoints: np.ndarray, reference: np.ndarray) -> float:
    """The size of one ``[25, 3]`` pose against :func:`reference_lengths` (1: the bank's body across the image):
    the :data:`SCALE_RANK`-th largest of its bones' length ratios, the largest with fewer than
    :data:`SCALE_MIN_BONES` seen, NaN with none. A torso bending towards the camera is shorter, not smaller."""
    ratios = _scale_bone_lengths(keypoints) / np.where(reference > 0, reference, np.nan)
    ratios = np.sort(ratios[np.isfinite(ratios) & (ratios > 0)])[::-1]
    if not len(ratios):
        return math.nan
    return float(ratios[SCALE_RANK - 1] if len(ratios) >= SCALE_MIN_BONES else ratios[0])


def torso_lengths(keypoints: np.ndarray) -> np.ndarray:
    """``[..., 25, 3]`` poses -> ``[...]`` Neck-MidHip lengths (pixels; NaN where either joint is absent)."""
    kp = np.asarray(keypoints, np.float32)
    ok = (kp[..., NECK, 2] >= MIN_CONFIDENCE) & (kp[..., ROOT, 2] >= MIN_CONFIDENCE)
    length = np.linalg.norm(kp[..., NECK, :2] - kp[..., ROOT, :2], axis=-1)
    return np.where(ok & (length > 1e-3), length, np.nan)


Description = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def descriptor(keypoints: np.ndarray) -> Description:
    """Position- and scale-free description of ``[..., 25, 3]`` poses.

    Returns:
        ``[..., B, 2]`` bone vectors in torso lengths (B = len(DESCRIPTOR_BONES)), ``[..., B]`` bool bone present,
        ``[..., 4]`` bool face points (:data:`FACE_POINTS`) visible, ``[..., 4, 2]`` their offsets from the nose in
        head lengths (nose to neck; 0 where unseen).
    """
    kp = np.asarray(keypoints, np.float32)
    parents = np.array([a for a, _ in DESCRIPTOR_BONES])
    children = np.array([b for _, b in DESCRIPTOR_BONES])
    torso = torso_lengths(kp)
    vectors = (kp[..., children, :2] - kp[..., parents, :2]) / torso[..., None, None]
    present = (kp[..., parents, 2] >= MIN_CONFIDENCE) & (kp[..., children, 2] >= MIN_CONFIDENCE)
    present &= np.isfinite(torso)[..., None]
    face = kp[..., list(FACE_POINTS), 2] >= MIN_CONFIDENCE
    nose, neck = kp[..., J["Nose"], :], kp[..., J["Neck"], :]
    head = np.linalg.norm(nose[..., :2] - neck[..., :2], axis=-1)
    face &= (nose[..., None, 2] >= MIN_CONFIDENCE) & (neck[..., None, 2] >= MIN_CONFIDENCE) & (head[..., None] > 0)
    offsets = (kp[..., list(FACE_POINTS), :2] - nose[..., None, :2]) / np.maximum(head, 1e-6)[..., None, None]
    return (np.where(present[..., None], vectors, 0.0).astype(np.float32), present, face,
            np.where(face[..., None], offsets, 0.0).astype(np.float32))


def scene_places(keypoints: np.ndarray) -> np.ndarray:
    """``[..., 25, 3]`` poses -> ``[..., 2]`` where each person stands, in the poses' pixels: the mid-hip (NaN where
    it is not seen)."""
    kp = np.asarray(keypoints, np.float32)
    return np.where((kp[..., ROOT, 2] >= MIN_CONFIDENCE)[..., None], kp[..., ROOT, :2], np.nan)


def place_costs(places: np.ndarray, query: np.ndarray) -> np.ndarray:
    """``[N]`` retrieval cost of bank frames whose people stand at ``places`` (``[N, 2]``, :func:`scene_places`) for
    one ``[25, 3]`` query pose in the same pixels: :data:`PLACE_COST` per squared torso length of the query between
    the two places; 0 where either place or the query's torso is unknown."""
    here, torso = scene_places(query), torso_lengths(query)
    cost = PLACE_COST * (((places - here) / torso) ** 2).sum(-1)
    return np.nan_to_num(cost, nan=0.0)


def _distance_to_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``[..., 2]`` points, ``[..., 2]`` segment ends (broadcast) -> ``[...]`` distances."""
    ab = b - a
    t = np.clip(((p - a) * ab).sum(-1) / np.maximum((ab ** 2).sum(-1), 1e-9), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


# Every occluded bone's ends, in the order of OCCLUDED_BONES, and each group's share of them.
_OCCLUDED_ENDS = np.array([bone for bones in OCCLUDED_BONES.values() for bone in bones])
_OCCLUDED_SPLITS = np.cumsum([len(bones) for bones in OCCLUDED_BONES.values()])[:-1]
_OCCLUDED_REACH = np.repeat([OCCLUSION_REACH[g] for g in OCCLUDED_BONES],
                            [len(bones) for bones in OCCLUDED_BONES.values()])


def hand_overlaps(keypoints: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """How much each arm's elbow, wrist and hand tip lie on each group's parts, for ``[N, 25, 3]`` poses:
    ``{arm group: {group: [N]}}``, 0 (clear) to 3 per bone of the group (all three points on it)."""
    kp = np.asarray(keypoints, np.float64)
    torso = torso_lengths(kp)
    scale = np.nan_to_num(torso, nan=1.0)[:, None, None]
    ends = kp[:, _OCCLUDED_ENDS]  # [N, bones, 2 ends, 3]
    bones_seen = (ends[..., 2] >= MIN_CONFIDENCE).all(-1) & np.isfinite(torso)[:, None]  # [N, bones]
    overlaps: dict[str, dict[str, np.ndarray]] = {}
    for arm, (elbow, wrist) in (("right arm", _R_FOREARM), ("left arm", _L_FOREARM)):
        seen = (kp[:, elbow, 2] >= MIN_CONFIDENCE) & (kp[:, wrist, 2] >= MIN_CONFIDENCE)
        forearm = kp[:, wrist, :2] - kp[:, elbow, :2]
        tip = kp[:, wrist, :2] + forearm / np.maximum(np.linalg.norm(forearm, axis=-1), 1e-6)[:, None] * (
            PARTS[-1].extend * np.nan_to_num(torso)[:, None])
        points = np.stack([kp[:, elbow, :2], kp[:, wrist, :2], tip], 1)[:, None]  # [N, 1, 3 points, 2]
        near = _distance_to_segment(points, ends[:, :, None, 0, :2], ends[:, :, None, 1, :2]) / scale
        on = np.clip(1.0 - near / _OCCLUDED_REACH[:, None], 0.0, 1.0).sum(-1)  # [N, bones]
        on = np.where(bones_seen & seen[:, None], on, 0.0)
        overlaps[arm] = {group: part.sum(1) for group, part in zip(OCCLUDED_BONES, np.split(on, _OCCLUDED_SPLITS, 1))}
    return overlaps


def occlusion_costs(bank: dict[str, dict[str, np.ndarray]], query: np.ndarray) -> dict[str, np.ndarray]:
    """Per group, ``[N]`` retrieval cost from the bank's :func:`hand_overlaps` for one ``[25, 3]`` query pose.

    A bank frame whose hand lies on a group's parts would leave a hole where it is cut out of them; a frame whose
    hand lies on the head, torso or a leg where the query's does not would carry their pixels away with the arm (a
    face beside a raised glove; a wedge of trousers swinging with a hand taken from a hip)."""
    query_overlaps = hand_overlaps(np.asarray(query)[None])
    costs = {group: np.zeros_like(bank["right arm"]["core"]) for group in GROUPS}
    for arm, on in bank.items():
        for group, overlap in on.items():
            costs[group] += OCCLUSION_COST * overlap
            costs[arm] += OCCLUSION_COST * np.maximum(overlap - query_overlaps[arm][group][0], 0.0)
    return costs


def group_costs(bank: Description, query: np.ndarray) -> dict[str, np.ndarray]:
    """Retrieval cost of every bank frame (described by :func:`descriptor`) for one ``[25, 3]`` query pose, per
    group: ``{group: [N]}``, lower is nearer (squared torso lengths summed over the group's bones and the facing
    bones, and the head's turn in head lengths; the upper arms, lighter, for the head and torso)."""
    vectors, present, face, offsets = bank
    q_vec, q_present, q_face, q_offsets = descriptor(query)
    per_bone = np.where(present, ((vectors - q_vec) ** 2).sum(-1), MISSING_COST) * q_present  # [N, B]
    turn = np.where(face & q_face, ((offsets - q_offsets) ** 2).sum(-1), 0.0).sum(1)
    shared = per_bone[:, list(FACING_BONES)].sum(1) + FACE_COST * (face != q_face).sum(1) + HEAD_TURN_COST * turn
    costs = {g: shared + per_bone[:, list(bones)].sum(1) for g, bones in GROUP_OWN_BONES.items()}
    costs["core"] = costs["core"] + TORSO_ARM_COST * per_bone[:, list(UPPER_ARM_BONES)].sum(1)
    return costs


def _segment_mask(shape: tuple[int, int], lines: list[tuple[np.ndarray, np.ndarray]],
                  polygon: np.ndarray | None) -> np.ndarray:
    canvas = np.full(shape, 255, np.uint8)
    for a, b in lines:
        cv2.line(canvas, tuple(int(v) for v in np.round(a)), tuple(int(v) for v in np.round(b)), 0, 1)
    if polygon is not None:
        cv2.fillConvexPoly(canvas, np.round(polygon).astype(np.int32), 0)
    return canvas


def part_lines(part: Part, kp: np.ndarray, torso: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """The segments (pixel end points) drawn for ``part`` of one ``[25, 3]`` pose; its hand or foot line too."""
    present = kp[:, 2] >= MIN_CONFIDENCE
    lines = [(kp[a, :2], kp[b, :2]) for a, b in part.lines if present[a] and present[b]]
    if part.extend and part.bone is not None and present[part.bone[0]] and present[part.bone[1]]:
        a, b = kp[part.bone[0], :2], kp[part.bone[1], :2]
        direction = (b - a) / max(float(np.linalg.norm(b - a)), 1e-6)
        lines.append((b, b + direction * part.extend * torso))
    return lines


def part_labels(mask: np.ndarray, keypoints: np.ndarray) -> np.ndarray:
    """``[H, W]`` uint8 part index (into :data:`PARTS`, :data:`NO_PART` off the person) of each pixel of a person
    ``mask`` (``[H, W]``, non-zero on the person) whose pose is ``keypoints`` (``[25, 3]``, same pixels)."""
    kp = np.asarray(keypoints, np.float32)
    labels = np.full(mask.shape, NO_PART, np.uint8)
    torso = float(torso_lengths(kp))
    person = mask > 127
    if not np.isfinite(torso) or not person.any():
        return labels
    ys, xs = np.nonzero(person)
    pad = 2
    y0, y1 = max(0, ys.min() - pad), min(mask.shape[0], ys.max() + pad + 1)
    x0, x1 = max(0, xs.min() - pad), min(mask.shape[1], xs.max() + pad + 1)
    local = kp.copy()
    local[:, :2] -= (x0, y0)
    shape = (y1 - y0, x1 - x0)
    distances = np.full((len(PARTS), *shape), np.inf, np.float32)
    drawn = np.zeros((len(PARTS), *shape), bool)
    beyond_keep: dict[int, np.ndarray] = {}
    corners = [j for j in TORSO_CORNERS if local[j, 2] >= MIN_CONFIDENCE]
    for i, part in enumerate(PARTS):
        lines = part_lines(part, local, torso)
        polygon = local[corners, :2] if i == TORSO and len(corners) >= 3 else None
        if not lines and polygon is None:
            continue
        d = cv2.distanceTransform(_segment_mask(shape, lines, polygon), cv2.DIST_L2, 3)
        distances[i] = np.where(d <= part.reach * torso, d + part.bias * torso, np.inf)
        drawn[i] = d == 0
        if i in ARM_ENDS:
            beyond_keep[i] = d > part.keep * torso
    person = person[y0:y1, x0:x1]
    reached_by_others = np.isfinite(distances[_UNLIMITED]).any(0)
    for i, beyond in beyond_keep.items():
        distances[i][beyond & reached_by_others] = np.inf
    nearest = distances.argmin(0)
    for i in range(len(PARTS)):
        cut_off = _detached(person & (nearest == i), drawn[i])
        if cut_off.any():
            distances[i][cut_off] = np.inf
            nearest[cut_off] = distances[:, cut_off].argmin(0)
    reached = np.isfinite(distances.min(0))
    labels[y0:y1, x0:x1] = np.where(person & reached, nearest, NO_PART)
    return labels


def _detached(region: np.ndarray, on_lines: np.ndarray) -> np.ndarray:
    """``[H, W]`` bool: the pieces of a part's ``region`` that hold none of its own drawn pixels (``on_lines``),
    where some piece does hold one: pixels beside another part that lies across it (trousers beside a hand resting
    on a thigh), which would swing away from the body when the part moves."""
    count, pieces = cv2.connectedComponents(region.astype(np.uint8), connectivity=8)
    if count <= 2:
        return np.zeros_like(region)
    anchored = np.unique(pieces[region & on_lines])
    if not len(anchored):
        return np.zeros_like(region)
    return region & ~np.isin(pieces, anchored)


def bones_on_mask(mask: np.ndarray, keypoints: np.ndarray, bones: tuple[tuple[int, int], ...]) -> np.ndarray:
    """``[len(bones)]`` share of 9 points along the middle 60 % of each bone of a ``[25, 3]`` pose that lie on the
    ``[H, W]`` person mask (non-zero on the person; outside the picture counts as off it); NaN where the pose lacks
    the bone. The bones' ends are left out: they lie on joints other parts share."""
    along = np.linspace(0.2, 0.8, 9)[:, None]
    kp = np.asarray(keypoints, np.float32)
    shares = np.full(len(bones), np.nan)
    for i, (a, b) in enumerate(bones):
        if kp[a, 2] < MIN_CONFIDENCE or kp[b, 2] < MIN_CONFIDENCE:
            continue
        points = kp[a, :2] + along * (kp[b, :2] - kp[a, :2])
        x = np.clip(np.round(points[:, 0]).astype(int), 0, mask.shape[1] - 1)
        y = np.clip(np.round(points[:, 1]).astype(int), 0, mask.shape[0] - 1)
        inside = (points[:, 0] >= 0) & (points[:, 0] < mask.shape[1]) & (points[:, 1] >= 0) & (
            points[:, 1] < mask.shape[0])
        shares[i] = ((mask[y, x] > 127) & inside).mean()
    return shares


def parts_seen(masks: list[np.ndarray], keypoints: np.ndarray) -> dict[str, tuple[float, float]]:
    """For each part of :data:`SEEN_PARTS`, over frames (``[H, W]`` person masks, non-zero on the person, and their
    ``[N, 25, 3]`` poses in the same pixels): the share whose pose has the part's bones, and the share of those
    whose mask holds the middle of each bone (:func:`bones_on_mask`, half of the points over the part's bones;
    NaN without such frames)."""
    seen: dict[str, tuple[float, float]] = {}
    for part, bones in SEEN_PARTS.items():
        shares = [bones_on_mask(mask, kp, bones) for mask, kp in zip(masks, keypoints)]
        shown = [share.mean() >= 0.5 for share in shares if not np.isnan(share).any()]
        seen[part] = (len(shown) / max(len(masks), 1), float(np.mean(shown)) if shown else math.nan)
    return seen


def off_mask_costs(masks: np.ndarray, keypoints: np.ndarray, members: np.ndarray) -> dict[str, np.ndarray]:
    """Per group, ``[N]`` retrieval cost of the bank frames ``members`` (of ``[T, H, W]`` masks and ``[T, 25, 3]``
    poses in bank pixels) whose pose puts the group's limb off the person's mask: :data:`OFF_MASK_COST` times the
    share of its worst bone's middle off the mask (:func:`bones_on_mask`; 0 for bones the pose lacks)."""
    bones = {group: tuple(DESCRIPTOR_BONES[b] for b in own) for group, own in GROUP_OWN_BONES.items()}
    costs = {group: np.zeros(len(members), np.float32) for group in bones}
    for i, t in enumerate(members):
        mask, kp = np.asarray(masks[t]), keypoints[t]
        for group, own in bones.items():
            on = bones_on_mask(mask, kp, own)
            costs[group][i] = OFF_MASK_COST * (1.0 - np.nanmin(on)) if not np.isnan(on).all() else 0.0
    return costs


def colour_index(image: np.ndarray) -> np.ndarray:
    """``[H, W]`` int bin of each pixel of an ``[H, W, 3]`` uint8 image: :data:`COLOUR_LEVELS` levels a channel."""
    step = 256 // COLOUR_LEVELS
    bins = image // step
    return (bins[..., 0].astype(np.int32) * COLOUR_LEVELS + bins[..., 1]) * COLOUR_LEVELS + bins[..., 2]


def part_colours(images: list[np.ndarray], labels: list[np.ndarray]) -> np.ndarray:
    """``[len(PARTS), COLOUR_LEVELS**3]``: how often each part of the person takes each colour (one in a bin added
    everywhere, each row summing to 1), from frames' ``[H, W, 3]`` uint8 images and their :func:`part_labels`."""
    counts = np.ones((len(PARTS), COLOUR_LEVELS ** 3))
    for image, label in zip(images, labels):
        on = label != NO_PART
        np.add.at(counts, (label[on], colour_index(image)[on]), 1)
    return counts / counts.sum(1, keepdims=True)


def _paint_nearest(image: np.ndarray, source: np.ndarray, holes: np.ndarray) -> np.ndarray:
    """A copy of ``image`` (``[H, W, 3]``) whose ``holes`` pixels take the colour of the nearest ``source`` pixel (both
    ``[H, W]`` bool, ``source`` not empty)."""
    _, nearest = cv2.distanceTransformWithLabels(np.where(source, 0, 255).astype(np.uint8), cv2.DIST_L2, 5,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
    ys, xs = np.nonzero(source)  # DIST_LABEL_PIXEL numbers the zero pixels from 1 in raster order
    hy, hx = np.nonzero(holes)
    taken = nearest[hy, hx] - 1
    painted = image.copy()
    painted[hy, hx] = image[ys[taken], xs[taken]]
    return painted


def clean_strays(image: np.ndarray, labels: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """``image`` (``[H, W, 3]`` uint8, ``labels`` its :func:`part_labels`) with every pixel outside the hands whose
    colour is :data:`STRAY_RATIO` times likelier in a hand than in its own part (``colours``: :func:`part_colours` of
    the bank) painted with the nearest other person pixel's colour. A hand the pose put elsewhere lies in another
    part's region and would move with that part: a glove between the thighs of every pose the legs serve."""
    on = labels != NO_PART
    index = colour_index(image)
    own = colours[np.where(on, labels, 0), index]
    stray = on & ~np.isin(labels, HAND_PARTS) & (own * STRAY_RATIO < colours[list(HAND_PARTS)][:, index].max(0))
    keep = on & ~stray
    if not stray.any() or not keep.any():
        return image
    return _paint_nearest(image, keep, stray)


def fill_torso(image: np.ndarray, labels: np.ndarray, keypoints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The torso's region of one frame: its own pixels plus the quadrilateral between shoulders and hips
    (``[H, W]`` bool), and ``image`` with the pixels of that region which limbs cover filled in from the torso
    around them, so a torso moved out from behind an arm shows no hole. Nothing beyond the shoulders is added: arm
    pixels there, moved under an upper arm taken from a frame whose arm lies at another angle, stand out as square
    pads (docs/methods/warped_prior.md)."""
    region = labels == TORSO
    corners = [j for j in TORSO_CORNERS if keypoints[j, 2] >= MIN_CONFIDENCE]
    if len(corners) < 3 or not region.any():
        return image, region
    quad = np.zeros(labels.shape, np.uint8)
    cv2.fillConvexPoly(quad, np.round(keypoints[corners, :2]).astype(np.int32), 1)
    holes = (quad > 0) & ~region & (labels != NO_PART)  # limb pixels only: the background stays out
    if not holes.any():
        return image, region
    # Each hole pixel takes the colour of the nearest torso pixel (inpainting would draw on the background too).
    return _paint_nearest(image, region, holes), region | holes


def similarity(src: np.ndarray, dst: np.ndarray, scale: float | None = None) -> np.ndarray:
    """``[2, 3]`` least-squares similarity (rotation, uniform scale, translation) taking ``[n, 2]`` points ``src``
    onto ``dst`` (n >= 2): Umeyama's (1991) solution, which in the plane has this closed form. ``scale``: the
    least-squares rotation and translation at this scale instead (points a few pixels apart make a noisy scale)."""
    mu_s, mu_d = src.mean(0), dst.mean(0)
    s, d = src - mu_s, dst - mu_d
    variance = max(float((s ** 2).sum()), 1e-9 * len(src))
    cos = float((s * d).sum()) / variance
    sin = float((s[:, 0] * d[:, 1] - s[:, 1] * d[:, 0]).sum()) / variance
    if scale is not None:
        norm = max(math.hypot(cos, sin), 1e-12)
        cos, sin = cos / norm * scale, sin / norm * scale
    x, y = float(mu_d[0] - cos * mu_s[0] + sin * mu_s[1]), float(mu_d[1] - sin * mu_s[0] - cos * mu_s[1])
    return np.array([[cos, -sin, x], [sin, cos, y]])


def bone_affine(a: np.ndarray, b: np.ndarray, a2: np.ndarray, b2: np.ndarray, across: float) -> np.ndarray:
    """``[2, 3]`` affine taking segment ``a -> b`` onto ``a2 -> b2``: rotated with it, stretched along it to its
    length (at most ``MAX_STRETCH`` x ``across``) and scaled by ``across`` across it; ``a`` lands on ``a2``."""
    # In plain floats: a warp makes dozens of these, and numpy's per-call cost on 2-vectors dominated it.
    ux, uy, vx, vy = float(b[0] - a[0]), float(b[1] - a[1]), float(b2[0] - a2[0]), float(b2[1] - a2[1])
    length, length2 = math.hypot(ux, uy), math.hypot(vx, vy)
    if length < 1e-6 or length2 < 1e-6:
        l00, l01, l10, l11 = across, 0.0, 0.0, across
    else:
        ux, uy, vx, vy = ux / length, uy / length, vx / length2, vy / length2
        along = min(length2 / length, MAX_STRETCH * across)
        # R(v) @ diag(along, across) @ R(u).T, R(w) the rotation taking the x axis onto w
        l00, l01 = along * vx * ux + across * vy * uy, along * vx * uy - across * vy * ux
        l10, l11 = along * vy * ux - across * vx * uy, along * vy * uy + across * vx * ux
    ax, ay = float(a[0]), float(a[1])
    return np.array([[l00, l01, float(a2[0]) - l00 * ax - l01 * ay], [l10, l11, float(a2[1]) - l10 * ax - l11 * ay]])


def part_transform(part: Part, src: np.ndarray, dst: np.ndarray,
                   torso: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray | None:
    """``[2, 3]`` affine moving ``part`` from pose ``src`` to pose ``dst`` (``[25, 3]`` pixels), or None when a
    joint it needs is absent in either. ``torso``: :func:`torso_moves` (the torso's move, and the similarity whose
    scale sizes the other parts)."""
    if torso is None:
        return None
    move, torso_fit = torso
    if part.bone is None:
        return move
    a, b = part.bone
    if min(src[a, 2], src[b, 2], dst[a, 2], dst[b, 2]) < MIN_CONFIDENCE:
        return None
    scale = math.hypot(torso_fit[0, 0], torso_fit[1, 0])  # a similarity's first column: scale times a unit vector
    shared = [j for j in part.fit if src[j, 2] >= MIN_CONFIDENCE and dst[j, 2] >= MIN_CONFIDENCE]
    if len(shared) >= MIN_FIT_JOINTS:
        return similarity(src[shared, :2], dst[shared, :2], scale)
    if part.rigid:  # a similarity about the child joint, turned with the bone
        bone, bone2 = src[b, :2] - src[a, :2], dst[b, :2] - dst[a, :2]
        return bone_affine(src[b, :2], src[b, :2] + bone, dst[b, :2], dst[b, :2] + _turned(bone, bone2, scale), scale)
    return bone_affine(src[a, :2], src[b, :2], dst[a, :2], dst[b, :2], scale)


def _turned(vector: np.ndarray, direction: np.ndarray, scale: float) -> np.ndarray:
    """``vector`` scaled by ``scale`` and turned to point along ``direction``."""
    norm = max(math.hypot(direction[0], direction[1]), 1e-6)
    return direction / norm * (math.hypot(vector[0], vector[1]) * scale)


def torso_moves(src: np.ndarray, dst: np.ndarray, scale: float = math.nan
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """The torso's ``[2, 3]`` move from pose ``src`` to ``dst`` (``[25, 3]``) and the similarity whose scale sizes
    the other parts; None with fewer than 2 shared torso joints. ``scale``: the body's size in ``dst`` over that in
    ``src`` (:func:`body_scale`): the torso is then stretched along its spine (neck to mid-hip) onto the target's
    and scaled by ``scale`` across it (without a neck or mid-hip in both poses: the similarity's turn at ``scale``),
    and the other parts take ``scale``; NaN: the least-squares similarity of the torso's joints does both (its scale
    shrinks with a torso bending towards the camera, and the head with it)."""
    shared = [j for j in TORSO_JOINTS if src[j, 2] >= MIN_CONFIDENCE and dst[j, 2] >= MIN_CONFIDENCE]
    if len(shared) < 2:
        return None
    points, targets = src[shared, :2].astype(np.float64), dst[shared, :2].astype(np.float64)
    if not math.isfinite(scale):
        fit = similarity(points, targets)
        return fit, fit
    fit = similarity(points, targets, scale)
    if min(src[NECK, 2], src[ROOT, 2], dst[NECK, 2], dst[ROOT, 2]) < MIN_CONFIDENCE:
        return fit, fit
    return bone_affine(src[NECK, :2], src[ROOT, :2], dst[NECK, :2], dst[ROOT, :2], scale), fit


@dataclass
class Source:
    """One bank frame ready to be cut into parts: its ``[H, W, 3]`` uint8 image, the same with the torso's hidden
    pixels filled in (:func:`fill_torso`), ``[H, W]`` uint8 part labels, the torso's ``[H, W]`` bool region, its
    ``[25, 3]`` pose in bank pixels and the share of its mask's pixels no part reaches (:data:`MASK_LEAK_LIMIT`)."""

    image: np.ndarray
    torso_image: np.ndarray
    labels: np.ndarray
    torso: np.ndarray
    keypoints: np.ndarray
    leak: float = 0.0
    layers: dict[int, tuple[int, int, np.ndarray] | None] = dataclasses.field(default_factory=dict, repr=False)

    def region(self, part: int) -> np.ndarray:
        """``[H, W]`` bool: the pixels of part ``part``, grown by :data:`OVERLAP_PIXELS` over the person, though not
        over a forearm or hand (:data:`ARM_ENDS`: a glove's edge would stay behind on the hip when the hand moves
        away)."""
        inside = self.torso if part == TORSO else self.labels == part
        if not inside.any():
            return inside
        kernel = np.ones((2 * OVERLAP_PIXELS + 1,) * 2, np.uint8)
        grown = cv2.dilate(inside.astype(np.uint8), kernel) > 0
        person, clear_of_arm_ends = self._overlap
        return inside | (grown & (person if part in ARM_ENDS else clear_of_arm_ends))

    @functools.cached_property
    def _overlap(self) -> tuple[np.ndarray, np.ndarray]:
        """The ``[H, W]`` bool pixels a part may grow over: the person's, and the person's but its forearms' and
        hands' (each part's region is cut once, but all of them share these)."""
        person = (self.labels != NO_PART) | self.torso
        return person, person & ~np.isin(self.labels, ARM_ENDS)

    def layer(self, part: int) -> tuple[int, int, np.ndarray] | None:
        """Part ``part`` cut out of its box, cached (every pose warped from this frame moves the same cut):
        ``(x0, y0, [h, w, 4] uint8)`` with colour premultiplied by alpha and alpha 0 or 255, ``(x0, y0)`` the box's
        top-left corner in the source; None where the part has no pixels."""
        if part not in self.layers:
            inside = self.region(part).astype(np.uint8)
            x0, y0, w, h = cv2.boundingRect(inside)
            cut = None
            if w and h:
                inside = inside[y0:y0 + h, x0:x0 + w, None]
                image = self.torso_image if part == TORSO else self.image
                cut = (x0, y0, np.concatenate([image[y0:y0 + h, x0:x0 + w] * inside, inside * 255], axis=2))
            self.layers[part] = cut
        return self.layers[part]


def warp_parts(sources: dict[str, Source], target: np.ndarray, size: tuple[int, int],
               reference: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Paint every part of its group's source onto the ``[25, 3]`` ``target`` pose.

    Args:
        sources: the source frame of each retrieval group (:data:`GROUPS`).
        target: the pose to render, in bank pixels.
        size: ``(width, height)`` of the bank image.
        reference: :func:`reference_lengths` of the bank, by which each pose's size is measured
            (:func:`body_scale`; None: the torso's similarity sizes the parts).

    Returns:
        ``[H, W, 3]`` float32 colour premultiplied by alpha (0-255) and ``[H, W]`` float32 alpha in [0, 1].
    """
    width, height = size
    colour = np.zeros((height, width, 3), np.float32)
    alpha = np.zeros((height, width), np.float32)
    size_of = (lambda kp: body_scale(kp, reference)) if reference is not None else (lambda kp: math.nan)
    target_size = size_of(target)
    moves = {g: torso_moves(s.keypoints, target, target_size / size_of(s.keypoints)) for g, s in sources.items()}
    for i, part in enumerate(PARTS):
        source = sources[part.group]
        m = part_transform(part, source.keypoints, target, moves[part.group])
        if m is None:
            continue
        cut = source.layer(i)
        if cut is None:
            continue
        x0, y0, layer = cut
        x1, y1 = x0 + layer.shape[1], y0 + layer.shape[0]
        m = m.copy()
        m[:, 2] += m[:, :2] @ (x0, y0)  # the layer's origin is (x0, y0) of the source
        # Only the destination box the layer can reach is warped.
        corners = np.array([[0, 0, 1], [x1 - x0, 0, 1], [0, y1 - y0, 1], [x1 - x0, y1 - y0, 1]], np.float64) @ m.T
        dx0, dy0 = (max(0, int(np.floor(v)) - 1) for v in corners.min(0))
        dx1, dy1 = min(width, int(np.ceil(corners[:, 0].max())) + 2), min(height, int(np.ceil(corners[:, 1].max())) + 2)
        if dx1 <= dx0 or dy1 <= dy0:
            continue
        m[:, 2] -= (dx0, dy0)
        moved = cv2.warpAffine(layer, m, (dx1 - dx0, dy1 - dy0), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0).astype(np.float32)
        a = moved[..., 3] * (1 / 255)
        under = 1 - a
        # In place over the box: colour = moved + (1 - a) * colour, alpha = a + (1 - a) * alpha.
        colour_box, alpha_box = colour[dy0:dy1, dx0:dx1], alpha[dy0:dy1, dx0:dx1]
        colour_box *= under[..., None]
        colour_box += moved[..., :3]
        alpha_box *= under
        alpha_box += a
    return colour, alpha


class FrameBank:
    """The target's training frames indexed by pose, and the warped prior they give for any pose.

    Args:
        frames: ``[T, H, W, 3]`` uint8 frames of the target video in bank framing (may be memory-mapped).
        masks: ``[T, H, W]`` uint8 person masks in the same framing (:mod:`stage2_video.masks`).
        keypoints: ``[T, 25, 3]`` the frames' poses in bank pixels.
        members: frame indices the bank may return (training frames with a usable pose and a mask).
        cache_size: source frames kept cut into parts (cutting costs a few milliseconds).
        candidates: how many retrieved frames make one prior (odd): the per-pixel median of their warps
            (:class:`PriorRenderer`).
        scene: ``[T, 25, 3]`` the frames' poses in the video's pixels, where retrieval compares the places people
            stand at (:func:`place_costs`; None: it does not).
    """

    def __init__(self, frames: np.ndarray, masks: np.ndarray, keypoints: np.ndarray, members: np.ndarray,
                 cache_size: int = 512, candidates: int = 1, scene: np.ndarray | None = None) -> None:
        if candidates < 1 or candidates % 2 == 0:
            raise ValueError(f"the prior's candidates must be an odd count, got {candidates}")
        self.frames, self.masks = frames, masks
        self.candidates = candidates
        self.keypoints = np.asarray(keypoints, np.float32)
        self.members = np.asarray(members, np.int64)
        self.size = (frames.shape[2], frames.shape[1])
        self.described = descriptor(self.keypoints[self.members])
        self.overlaps = hand_overlaps(self.keypoints[self.members])
        self.places = None if scene is None else scene_places(np.asarray(scene)[self.members])
        self.reference = reference_lengths(self.keypoints[self.members])
        sample = self.members[np.linspace(0, len(self.members) - 1, min(COLOUR_FRAMES, len(self.members))).astype(int)]
        sample_masks = [np.asarray(self.masks[t]) for t in sample]
        self.colours = part_colours([np.asarray(self.frames[t]) for t in sample],
                                    [part_labels(mask, self.keypoints[t]) for mask, t in zip(sample_masks, sample)])
        self.seen = parts_seen(sample_masks, self.keypoints[sample])
        self.off_mask = off_mask_costs(self.masks, self.keypoints, self.members)
        self._sources: OrderedDict[int, Source] = OrderedDict()
        # Members found to be failed segmentations when first cut (:data:`MASK_LEAK_LIMIT`); never retrieved again.
        self.leaking = np.zeros(len(self.members), bool)
        self._cache_size = cache_size

    def __len__(self) -> int:
        return len(self.members)

    def hidden_parts(self) -> list[str]:
        """The parts of :data:`SEEN_PARTS` the target video shows in fewer than :data:`SEEN_SHARE` of the bank's
        frames where its pose places them (hidden behind something), or whose bones its poses hardly have (outside
        the picture: fewer than :data:`MIN_POSED_SHARE` of the frames)."""
        return [part for part, (posed, shown) in self.seen.items()
                if posed < MIN_POSED_SHARE or shown < SEEN_SHARE]

    def source(self, t: int) -> Source:
        """Frame ``t`` cut into parts (cached)."""
        if t in self._sources:
            self._sources.move_to_end(t)
            return self._sources[t]
        kp = self.keypoints[t]
        mask = np.asarray(self.masks[t])
        labels = part_labels(mask, kp)
        image = clean_strays(np.asarray(self.frames[t]), labels, self.colours)
        torso_image, torso = fill_torso(image, labels, kp)
        person = mask > 127
        leak = float((labels[person] == NO_PART).mean()) if person.any() else 0.0
        source = Source(image, torso_image, labels, torso, kp, leak=leak)
        self._sources[t] = source
        if len(self._sources) > self._cache_size:
            self._sources.popitem(last=False)
        return source

    def retrieve(self, query: np.ndarray, exclude: tuple[int, int] | None = None,
                 previous: dict[str, int] | None = None, scene: np.ndarray | None = None) -> dict[str, int]:
        """The bank frame (video frame index) of each group for one ``[25, 3]`` pose (bank pixels).

        ``exclude``: a ``[start, stop)`` range of frame indices never returned (when it covers the whole bank, only
        the frames farthest from its centre are allowed); ``previous``: last choices, kept while within
        :data:`HYSTERESIS` of the best; ``scene``: the same pose in the video's pixels, to prefer frames where the
        person stood near it (with the bank's ``scene``).
        """
        return self.choices(query, 1, exclude, previous, scene)[0]

    def choices(self, query: np.ndarray, count: int, exclude: tuple[int, int] | None = None,
                previous: dict[str, int] | None = None, scene: np.ndarray | None = None) -> list[dict[str, int]]:
        """Up to ``count`` choices of a bank frame per group for one ``[25, 3]`` pose (bank pixels): the first is
        :meth:`retrieve`'s (``exclude``, ``previous`` and ``scene`` as there), the k-th next takes each group's k-th
        nearest other frame (fewer when fewer frames are allowed)."""
        costs = group_costs(self.described, query)
        occlusion = occlusion_costs(self.overlaps, query)
        if self.places is not None and scene is not None:
            place = place_costs(self.places, scene)
            costs = {group: cost + place for group, cost in costs.items()}
        allowed = np.ones(len(self.members), bool)
        if exclude is not None:
            allowed = (self.members < exclude[0]) | (self.members >= exclude[1])
            if not allowed.any():  # a bank shorter than the window: keep the farthest frames
                distance = np.abs(self.members - (exclude[0] + exclude[1] - 1) / 2)
                allowed = distance == distance.max()
        costs = {group: cost + occlusion[group] + self.off_mask[group] for group, cost in costs.items()}
        while True:
            usable = allowed & ~self.leaking
            fallback = not usable.any()  # every allowed frame's mask failed: a leaking part rather than none
            chosen = self._nearest(costs, allowed if fallback else usable, count, previous)
            leaking = {t for choice in chosen for t in choice.values() if self.source(t).leak > MASK_LEAK_LIMIT}
            if fallback or not leaking:
                return chosen
            self.leaking |= np.isin(self.members, list(leaking))

    def _nearest(self, costs: dict[str, np.ndarray], allowed: np.ndarray, count: int,
                 previous: dict[str, int] | None) -> list[dict[str, int]]:
        """:meth:`choices` among the ``allowed`` members, given each group's ``[N]`` costs."""
        count = min(count, int(allowed.sum()))
        ranked = {}
        for group, cost in costs.items():
            cost = np.where(allowed, cost, np.inf)
            nearest = np.argsort(cost, kind="stable")[:count]
            best = int(nearest[0])
            if previous and group in previous:
                kept = np.flatnonzero(self.members == previous[group])
                if len(kept) and cost[kept[0]] <= cost[best] + HYSTERESIS:
                    best = int(kept[0])
            ranked[group] = [best] + [int(i) for i in nearest if i != best][:count - 1]
        return [{g: int(self.members[r[k]]) for g, r in ranked.items()} for k in range(count)]

    def warp(self, choice: dict[str, int], target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`warp_parts` of the chosen frames onto ``target`` (``[25, 3]`` bank pixels)."""
        return warp_parts({g: self.source(t) for g, t in choice.items()}, np.asarray(target, np.float32), self.size,
                          self.reference)


class PriorRenderer:
    """Warped priors for a sequence of poses, retrieval kept steady from one pose to the next.

    With a bank of ``candidates`` > 1 each prior is the per-pixel median of the warps of that many choices
    (:meth:`FrameBank.choices`), each over the plate: where most of the frames agree it is as sharp as one of them,
    and what only one of them gets wrong (pads at the shoulders, a glove over the face) drops out.

    ``exclude_frames``: frames within this many of a frame being learnt are not retrieved for it (training).
    """

    def __init__(self, bank: FrameBank, exclude_frames: int | None = None) -> None:
        self.bank = bank
        self.exclude_frames = exclude_frames
        self.previous: dict[str, int] | None = None

    def __call__(self, target: np.ndarray, plate_crop: np.ndarray, frame: int | None = None,
                 scene: np.ndarray | None = None) -> np.ndarray:
        """``[H, W, 4]`` uint8: the person warped onto ``target`` (``[25, 3]`` bank pixels) over ``plate_crop``
        (``[H, W, 3]`` uint8, bank size), and the warp's alpha. ``frame``: the video frame being learnt, whose
        neighbourhood is excluded; ``scene``: the pose in the video's pixels (:meth:`FrameBank.choices`)."""
        exclude = None
        if frame is not None and self.exclude_frames is not None:
            exclude = (frame - self.exclude_frames, frame + self.exclude_frames + 1)
        chosen = self.bank.choices(target, self.bank.candidates, exclude, self.previous, scene)
        self.previous = chosen[0]
        warps = [self.bank.warp(choice, target) for choice in chosen]
        prior = np.empty(plate_crop.shape[:2] + (4,), np.uint8)
        prior[..., :3], prior[..., 3] = plate_crop, 0
        # Only the box some warp touched differs from the plate.
        rows = np.flatnonzero(np.any([alpha.any(1) for _, alpha in warps], axis=0))
        cols = np.flatnonzero(np.any([alpha.any(0) for _, alpha in warps], axis=0))
        if len(rows):
            box = np.s_[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
            layers = np.empty((len(warps), rows[-1] + 1 - rows[0], cols[-1] + 1 - cols[0], 4), np.float32)
            for layer, (colour, alpha) in zip(layers, warps):
                layer[..., :3] = plate_crop[box]
                layer[..., :3] *= 1 - alpha[box][..., None]
                layer[..., :3] += colour[box]
                layer[..., 3] = alpha[box] * 255
            prior[box] = np.clip(median(list(layers)) + 0.5, 0, 255).astype(np.uint8)
        return prior


def median(images: list[np.ndarray]) -> np.ndarray:
    """The per-element median of an odd number of same-shape arrays (by min/max passes: ``np.median`` over a new
    axis is several times slower on images)."""
    rows = list(images)
    # Each bubble pass carries the largest left to the end and drops it; the median is the largest of the low half.
    while len(rows) > (len(images) + 1) // 2:
        for i in range(len(rows) - 1):
            rows[i], rows[i + 1] = np.minimum(rows[i], rows[i + 1]), np.maximum(rows[i], rows[i + 1])
        rows.pop()
    return functools.reduce(np.maximum, rows)


def bank_keypoints(keypoints: np.ndarray, framings: list[Framing]) -> np.ndarray:
    """``[T, 25, 3]`` poses (canvas pixels) in the pixels of their frames' bank framings."""
    out = np.asarray(keypoints, np.float32).copy()
    for t, framing in enumerate(framings):
        out[t, :, :2] = framing.points(out[t, :, :2])
    return out
