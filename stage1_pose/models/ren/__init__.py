"""Ren et al. 2020 (GAN with a pose perceptual loss), a stage-1 method.

The registry reads ``METHOD``, ``CONFIG`` and ``PRESETS`` from here."""

from stage1_pose.models.ren.model import REN_PRESETS as PRESETS
from stage1_pose.models.ren.model import RenConfig as CONFIG
from stage1_pose.models.ren.model import RenMethod as METHOD

__all__ = ["CONFIG", "METHOD", "PRESETS"]
