"""An output layer whose bones cannot change length: poses placed by forward kinematics along the BODY_25 tree.

Poses are in model coordinates (:func:`dancesynth.core.skeleton.normalize`): MidHip's row is its position, every
other joint's row its position relative to MidHip. A method with ``kinematic_output`` predicts per frame a raw
``[25, 2]`` array shaped like a pose: row ``ROOT`` is MidHip's position, every other row ``j`` is the direction (any
length) of the bone that ends at joint ``j``, from its parent in :data:`~dancesynth.core.skeleton.BODY25_TREE`.
:class:`KinematicOutput` normalises each direction and places every joint at its parent plus direction x that bone's
length, so a dance keeps one body whatever the network does. Lengths are per joint, ``[..., 25]`` in model
coordinates (torso lengths; the root's entry is unused): in training the real clip's own (its median body), at
generation the training data's mean body, which the layer keeps as a buffer updated while training (saved with the
weights). Normalising makes the output scale-invariant, and with Adam a scale-invariant output's effective step shrinks
as its raw rows grow (measured: rows 5-50x their bone's length after 60 epochs, and the model stopped learning), so in
training the layer also charges each raw row's distance from its bone's length (:meth:`KinematicOutput.take_penalty`).
"""

from __future__ import annotations

import numpy as np
import torch
import torch.distributed as dist
import torch.nn.functional as F
from torch import nn

from dancesynth.core.skeleton import BODY25_TREE, NUM_JOINTS, ROOT

# A direction shorter than this (model units) is too close to zero to trust; it is lengthened before normalising.
_MIN_NORM = 1e-4


def _tables() -> tuple[torch.Tensor, torch.Tensor]:
    """``parent [25]`` (the root its own parent) and ``ancestry [25, 25]``: ``ancestry[j, k] = 1`` where the bone
    ending at ``k`` lies on the path from the root to ``j`` (and ``ancestry[ROOT, ROOT] = 1``: its position)."""
    parent = torch.arange(NUM_JOINTS)
    ancestry = torch.zeros(NUM_JOINTS, NUM_JOINTS)
    ancestry[ROOT, ROOT] = 1.0
    for _, up, child in BODY25_TREE:
        parent[child] = up
        if up != ROOT:
            ancestry[child] = ancestry[up]
        ancestry[child, child] = 1.0
    return parent, ancestry


PARENT, ANCESTRY = _tables()


def bone_vectors(poses: torch.Tensor) -> torch.Tensor:
    """The raw form of ``[..., 25, 2]`` model-coordinate poses: the root's position, and for every other joint its
    position minus its parent's. ``forward_kinematics(bone_vectors(p), joint_lengths(p)) == p``."""
    relative = poses.index_fill(-2, torch.tensor([ROOT], device=poses.device), 0.0)
    raw = relative - relative[..., PARENT.to(poses.device), :]
    return torch.cat([raw[..., :ROOT, :], poses[..., ROOT:ROOT + 1, :], raw[..., ROOT + 1:, :]], dim=-2)


def joint_lengths(poses: torch.Tensor) -> torch.Tensor:
    """``[..., 25]`` length of the bone ending at each joint of ``[..., 25, 2]`` positions (0 for the root)."""
    return bone_vectors(poses).norm(dim=-1).index_fill(-1, torch.tensor([ROOT], device=poses.device), 0.0)


def forward_kinematics(raw: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
    """``[..., 25, 2]`` raw rows (root position + bone directions) and ``[..., 25]`` lengths (broadcast over the
    leading dimensions) -> ``[..., 25, 2]`` model-coordinate poses whose bone ending at joint ``j`` is
    ``lengths[j]`` long."""
    norm = raw.norm(dim=-1, keepdim=True).clamp_min(_MIN_NORM)
    placed = raw / norm * lengths[..., None]
    placed = torch.cat([placed[..., :ROOT, :], raw[..., ROOT:ROOT + 1, :], placed[..., ROOT + 1:, :]], dim=-2)
    return torch.einsum("jk,...kc->...jc", ANCESTRY.to(raw), placed)


def absolute_positions(poses: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """``[..., 25, 2]`` model coordinates (array or tensor) -> every joint's position relative to the canvas
    centre (model units)."""
    out = poses + poses[..., ROOT:ROOT + 1, :]
    out[..., ROOT, :] = poses[..., ROOT, :]
    return out


def _change_magnitudes(poses: torch.Tensor, order: int) -> torch.Tensor:
    """``[B, T, 25, 2]`` model coordinates -> ``[B, T - order, 25]`` length of each joint's ``order``-th frame
    difference on the canvas, with a gradient also where it is zero."""
    return (absolute_positions(poses).diff(n=order, dim=1).pow(2).sum(-1) + 1e-8).sqrt()


def joint_speeds(poses: torch.Tensor) -> torch.Tensor:
    """``[B, T, 25, 2]`` model coordinates -> ``[B, T - 1, 25]`` each joint's distance moved per frame on the canvas
    (model units: the root's motion counts for every joint, as in the measure of dances,
    :func:`dancesynth.core.motion.joint_speeds`), with a gradient also where a joint stands still."""
    return _change_magnitudes(poses, 1)


def speed_loss(fake: torch.Tensor, real: torch.Tensor) -> torch.Tensor:
    """L1 between the joint speeds of ``[B, T, 25, 2]`` generated and real poses: how fast each joint moves, not
    where to (an L1 on the motion vectors themselves pulls an uncertain model towards standing still). Speeds on the
    canvas, so a root that jitters is charged in every joint, not only in its own row of the pose loss."""
    return F.l1_loss(joint_speeds(fake), joint_speeds(real))


def acceleration_loss(fake: torch.Tensor, real: torch.Tensor) -> torch.Tensor:
    """L1 between the magnitudes of each joint's frame-to-frame change of velocity on the canvas, ``[B, T, 25, 2]``
    generated vs real: charges jitter (a shaking root shakes every joint) without asking for a direction."""
    return F.l1_loss(_change_magnitudes(fake, 2), _change_magnitudes(real, 2))


def motion_statistics_loss(fake: torch.Tensor, real: torch.Tensor) -> torch.Tensor:
    """How far ``[B, T, 25, 2]`` generated clips are from moving as much as ``[B', T', 25, 2]`` real clips: for speed
    and for acceleration magnitude on the canvas, the L1 gap between each joint's mean over the batch, summed over
    joints, relative to the real sum (each of the two terms: 0.4 = 40 % too much or too little motion). It asks for
    the amount of motion, not its timing, so an uncertain model cannot lower it by standing still (as it can a
    frame-wise L1). Batch means, not each clip's: a model that cannot tell a clip where the dancer sweeps an arm
    from one where they hold it is asked for the mean speed, where a per-clip gap is smallest at the median clip's
    (measured: wrists stuck at 0.55x real speed whatever the loss's weight)."""
    loss = fake.new_zeros(())
    for order in (1, 2):
        made = _change_magnitudes(fake, order).mean(dim=(0, 1))
        wanted = _change_magnitudes(real, order).mean(dim=(0, 1))
        loss = loss + (made - wanted).abs().sum() / wanted.sum().clamp_min(1e-6)
    return loss


def mean_raw_rows(poses: torch.Tensor) -> torch.Tensor:
    """``[B, T, 25, 2]`` real model-coordinate poses -> ``[25, 2]`` their mean :func:`bone_vectors` (the mean root
    position and mean bone vectors), averaged over every process of a distributed run."""
    rows = bone_vectors(poses).mean(dim=(0, 1))
    if dist.is_available() and dist.is_initialized():
        dist.all_reduce(rows)
        rows /= dist.get_world_size()
    return rows


class KinematicOutput(nn.Module):
    """Forward kinematics with the training data's mean body for generation (see the module docstring).

    Buffers ``body [25]`` (mean of the clip bodies seen in training, joint-indexed lengths) and ``seen`` (how many
    batches that mean holds).
    """

    def __init__(self) -> None:
        super().__init__()
        self.register_buffer("body", torch.ones(NUM_JOINTS))
        self.register_buffer("seen", torch.zeros(()))
        self._penalties: list[torch.Tensor] = []

    def observe(self, poses: torch.Tensor) -> torch.Tensor:
        """``[B, T, 25, 2]`` real training poses -> ``[B, 1, 25]`` each clip's body (median over frames of its
        bone lengths), folded into ``body``'s running mean when the module is training."""
        lengths = joint_lengths(poses).median(dim=1, keepdim=True).values
        if self.training:
            with torch.no_grad():
                mean = lengths.mean(dim=(0, 1))
                if dist.is_available() and dist.is_initialized():
                    # Every process holds an equal share of the global batch: the mean of means is its mean.
                    dist.all_reduce(mean)
                    mean /= dist.get_world_size()
                self.seen += 1
                self.body += (mean - self.body) / self.seen
        return lengths

    def forward(self, raw: torch.Tensor, lengths: torch.Tensor | None = None) -> torch.Tensor:
        """``[..., 25, 2]`` raw rows -> positions with ``lengths`` (``[..., 25]``, broadcastable; default the mean
        body). In training (with gradients) it also records the rows' length penalty for :meth:`take_penalty`."""
        lengths = self.body if lengths is None else lengths
        if self.training and torch.is_grad_enabled():
            gap = (raw.norm(dim=-1) - lengths).index_fill(-1, torch.tensor([ROOT], device=raw.device), 0.0)
            self._penalties.append(gap.square().mean() * NUM_JOINTS / (NUM_JOINTS - 1))
        return forward_kinematics(raw, lengths)

    def take_penalty(self) -> torch.Tensor:
        """Mean over the calls since the last take of ``mean((|raw row| - bone length)^2)`` (model units squared;
        0 when none), and forget them: add it to the loss once per training step."""
        penalties, self._penalties = self._penalties, []
        return torch.stack(penalties).mean() if penalties else self.body.new_zeros(())
