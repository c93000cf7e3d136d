"""The LSTM baseline, a stage-1 method.

The registry reads ``METHOD``, ``CONFIG`` and ``PRESETS`` from here."""

from stage1_pose.models.lstm.model import LSTM_PRESETS as PRESETS
from stage1_pose.models.lstm.model import LSTMBaseline as METHOD
from stage1_pose.models.lstm.model import LSTMConfig as CONFIG

__all__ = ["CONFIG", "METHOD", "PRESETS"]
