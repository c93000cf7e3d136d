"""Bone-length retargeting: a dance moved onto the target person's own skeleton.

Every bone of :data:`~dancesynth.core.skeleton.BODY25_LIMBS` keeps its direction in every frame and gets the
target's length, so every joint angle of the dance is unchanged while limbs that stage 1 stretched come out at
the target's proportions. The target's lengths are medians over the target video's poses
(:func:`target_bone_lengths`), stored with its appearance model.

Design: retargeting runs BEFORE the Everybody Dance Now normalisation (:mod:`stage2_video.normalize`), in the
source dance's pixel units. The target's lengths are in the target canvas's pixels, so :func:`retarget_onto`
first scales them by the ratio of the two bodies' heights (:func:`body_height`): the dance gets the target's
proportions at its own size and stays on its own canvas, and the normaliser then gives it the target's size and
place as before. Retargeting after the normaliser instead would replace the per-frame, depth-dependent scale it
applies (a person walking away from the camera shrinks) with one median length per bone. The normaliser measures
the body it is given, so that scaling of the lengths does not change its result, only keeps the intermediate
dance on its canvas.
"""

from __future__ import annotations

import numpy as np

from dancesynth.core.motion import bone_lengths
from dancesynth.core.skeleton import (
    BODY25_LIMBS,
    BODY25_TREE,
    JOINT_INDEX,
    PRESENT_CONFIDENCE,
    ROOT,
    PoseSequence,
    interpolate_missing,
)
from stage2_video.normalize import MIN_CONFIDENCE


# Bones summed into a body height: nose-neck, neck-midhip, and hip-knee-ankle (mean of the sides known).
def _bones(*pairs: tuple[str, str]) -> tuple[int, ...]:
    return tuple(BODY25_LIMBS.index((JOINT_INDEX[a], JOINT_INDEX[b])) for a, b in pairs)


_HEAD_TORSO = _bones(("Neck", "Nose"), ("Neck", "MidHip"))
_LEGS = (_bones(("RHip", "RKnee"), ("RKnee", "RAnkle")), _bones(("LHip", "LKnee"), ("LKnee", "LAnkle")))


def target_bone_lengths(seq: PoseSequence, min_confidence: float = MIN_CONFIDENCE) -> np.ndarray:
    """``[B]`` float64: per bone of BODY25_LIMBS, the median length in pixels of ``seq``'s canvas over the frames
    where both its joints have confidence ``>= min_confidence``.

    A bone never seen gets 0, meaning "unknown": :func:`retarget` keeps the dance's own length for it (BlazePose,
    for one, has no small toes, so the big-toe-small-toe bones of an extracted target are unknown).
    """
    lengths = bone_lengths(seq.xy)
    parent, child = np.array(BODY25_LIMBS).T
    seen = np.minimum(seq.confidence[:, parent], seq.confidence[:, child]) >= min_confidence
    return np.array([np.median(lengths[seen[:, b], b]) if seen[:, b].any() else 0.0 for b in range(len(BODY25_LIMBS))])


def body_height(lengths: np.ndarray) -> float:
    """Height in the unit of ``[B]`` bone ``lengths``: nose-neck + neck-midhip + hip-knee + knee-ankle (mean of
    the legs whose bones are known, i.e. > 0); NaN when a head or torso bone or both legs are unknown."""
    lengths = np.asarray(lengths, dtype=np.float64)
    known = np.where(lengths > 0, lengths, np.nan)
    legs = [known[list(leg)].sum() for leg in _LEGS]
    legs = [leg for leg in legs if np.isfinite(leg)]
    return float(known[list(_HEAD_TORSO)].sum() + np.mean(legs)) if legs else float("nan")


def _height_ratio(numerator: np.ndarray, denominator: np.ndarray) -> float:
    """``body_height(numerator) / body_height(denominator)``, or 1 when either is unknown."""
    ratio = body_height(numerator) / body_height(denominator)
    return ratio if np.isfinite(ratio) and ratio > 0 else 1.0


def retarget(seq: PoseSequence, lengths: np.ndarray) -> PoseSequence:
    """``seq`` with each bone at the length in ``[B]`` ``lengths`` (the unit of ``seq``'s pixels), on its canvas.

    Per frame, the skeleton is rebuilt from the root (MidHip) outwards: each bone keeps its direction and gets
    its length from ``lengths``, or keeps its own length where ``lengths`` is 0 or NaN (unknown). The root's
    displacement from its mean position (over the frames it is present) is scaled by ``body_height(lengths) /
    body_height(seq's median lengths)``, unknown lengths counted at the dance's own: a smaller body takes
    proportionally smaller steps around the same centre.

    Confidence is copied, so absent joints (confidence 0) stay absent. An absent joint's position is meaningless,
    so it is first estimated in time from the frames where the joint is present (linearly, as
    :func:`~dancesynth.core.skeleton.interpolate_missing` does); bones are retargeted along these estimates too,
    which keeps the whole body at one size in frames with dropped detections. A joint absent in every frame has
    no estimate: the bone to it is not rescaled, its child moves with its parent and so does what hangs off it.
    """
    lengths = np.asarray(lengths, dtype=np.float64)
    if lengths.shape != (len(BODY25_LIMBS),):
        raise ValueError(f"lengths must have shape [{len(BODY25_LIMBS)}], got {lengths.shape}")
    own = target_bone_lengths(seq, PRESENT_CONFIDENCE)
    ratio = _height_ratio(np.where(lengths > 0, lengths, own), own)
    present = seq.confidence > 0
    seen = present.any(axis=0)
    old = interpolate_missing(seq, PRESENT_CONFIDENCE).xy.astype(np.float64)
    new = old.copy()
    if seen[ROOT]:
        center = old[present[:, ROOT], ROOT].mean(axis=0)
        new[:, ROOT] = center + ratio * (old[:, ROOT] - center)
    for bone, parent, child in BODY25_TREE:
        vector = old[:, child] - old[:, parent]
        norm = np.linalg.norm(vector, axis=-1, keepdims=True)
        length = lengths[bone] if lengths[bone] > 0 else norm
        rescale = (norm > 0) & seen[parent] & seen[child]
        along = new[:, parent] + vector / np.where(norm > 0, norm, 1.0) * length
        new[:, child] = np.where(rescale, along, old[:, child] + new[:, parent] - old[:, parent])
    return seq.replace(np.concatenate([new, seq.confidence[..., None]], axis=-1).astype(np.float32))


def retarget_onto(poses: PoseSequence, target_lengths: np.ndarray) -> PoseSequence:
    """The pipeline's step before the EDN normalisation: ``poses`` with the target's proportions at its own size.

    ``target_lengths``: ``[B]`` from :func:`target_bone_lengths` of the target's poses (its canvas's pixels),
    as the appearance model stores them. They are scaled by ``body_height(poses' lengths) /
    body_height(target_lengths)`` into ``poses``' unit, so the root trajectory is unchanged (see the module
    docstring for why), then :func:`retarget` applies them.
    """
    target_lengths = np.asarray(target_lengths, dtype=np.float64)
    own = target_bone_lengths(poses, PRESENT_CONFIDENCE)
    scale = _height_ratio(own, np.where(target_lengths > 0, target_lengths, own))
    return retarget(poses, target_lengths * scale)
