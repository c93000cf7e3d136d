"""Dance Revolution (Huang et al. 2021), a stage-1 method.

The registry reads ``METHOD``, ``CONFIG`` and ``PRESETS`` from here."""

from stage1_pose.models.dance_revolution.model import DANCE_REVOLUTION_PRESETS as PRESETS
from stage1_pose.models.dance_revolution.model import DanceRevolution as METHOD
from stage1_pose.models.dance_revolution.model import DanceRevolutionConfig as CONFIG

__all__ = ["CONFIG", "METHOD", "PRESETS"]
