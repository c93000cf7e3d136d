"""Dancing to Music (Lee et al. 2019), a stage-1 method.

The registry reads ``METHOD``, ``CONFIG`` and ``PRESETS`` from here."""

from stage1_pose.models.dancing2music.model import DANCING2MUSIC_PRESETS as PRESETS
from stage1_pose.models.dancing2music.model import Dancing2MusicConfig as CONFIG
from stage1_pose.models.dancing2music.model import Dancing2MusicMethod as METHOD

__all__ = ["CONFIG", "METHOD", "PRESETS"]
