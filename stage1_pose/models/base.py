"""The contract between the shared stage-1 trainer and each music-to-pose method.

Tensors crossing it:
  * ``features``: ``[B, T, D]`` float32 music features of the method's ``feature_kind``, one row per pose frame
    (for ``waveform``, D = samples per pose frame), standardised with the training split's statistics.
  * ``beats``: ``[B, T]`` bool, True on the pose frames nearest to the song's beats
    (:func:`stage1_pose.beats.beats_on_frames`).
  * ``poses``: ``[B, T, 25, 2]`` float32 model coordinates from :func:`dancesynth.core.skeleton.normalize`.
  * ``style``: ``[B]`` int64 style label index.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import Any, ClassVar

import torch
from torch import nn


@dataclass
class Batch:
    """One training batch (see module docstring for shapes)."""

    features: torch.Tensor
    beats: torch.Tensor
    poses: torch.Tensor
    style: torch.Tensor

    def to(self, device: torch.device) -> "Batch":
        return Batch(self.features.to(device), self.beats.to(device), self.poses.to(device), self.style.to(device))


class Stage1Method(nn.Module, abc.ABC):
    """A music-to-pose method: its networks, its losses and how to sample from it.

    The trainer builds the method from its config, calls :meth:`configure_optimizers` once, then
    :meth:`training_step` per batch. Methods step their own optimizers through :meth:`optimize`, which
    is where the trainer hooks in gradient averaging for distributed training, so GANs with several
    optimizers and single-loss models share one loop.
    """

    method_name: ClassVar[str]
    feature_kind: ClassVar[str]

    def __init__(self, config: Any) -> None:
        super().__init__()
        self.config = config
        self._optimizers: dict[str, torch.optim.Optimizer] = {}
        self._sync_gradients = None

    @abc.abstractmethod
    def configure_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        """Name -> optimizer, created once by the trainer."""

    @abc.abstractmethod
    def training_step(self, batch: Batch, epoch: int) -> dict[str, float]:
        """One update (calling :meth:`optimize` for every optimizer it steps); returns scalars to log."""

    @abc.abstractmethod
    def generate(self, features: torch.Tensor, beats: torch.Tensor,
                 generator: torch.Generator | None = None) -> torch.Tensor:
        """``[B, T, D]`` features and ``[B, T]`` beat flags -> ``[B, T, 25, 2]`` model-coordinate poses, for any T;
        stochastic methods draw their noise from ``generator``."""

    def prepare_inference(self, precision: str = "fp32") -> None:
        """Called once after loading weights, before generating: a method may precompute or quantise weights
        (``precision`` ``"fp32"`` or ``"int8"``) for faster :meth:`generate`. Default: nothing to do."""

    def curriculum_state(self) -> dict[str, Any]:
        """JSON-serialisable training-schedule state saved in checkpoints (empty by default)."""
        return {}

    def load_curriculum_state(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`curriculum_state` returned."""

    def optimize(self, name: str, loss: torch.Tensor) -> None:
        """zero_grad, backward, (distributed gradient averaging), step for optimizer ``name``."""
        opt = self._optimizers[name]
        opt.zero_grad(set_to_none=True)
        loss.backward()
        if self._sync_gradients is not None:
            self._sync_gradients([p for g in opt.param_groups for p in g["params"]])
        opt.step()


def bce_with_constant_target(logits: torch.Tensor, target: float) -> torch.Tensor:
    """Binary cross-entropy of ``logits`` (any shape) against one label for all (GAN: 1 = real, 0 = generated)."""
    return nn.functional.binary_cross_entropy_with_logits(logits, torch.full_like(logits, target))
