"""The beat trackers' names and the default, without heavy imports, so argument parsers list them at once.

``learned``: this package's network and bar-pointer decoder (beats and downbeats); ``dsp``: onset tempograms and
dynamic programming, :func:`stage1_pose.beats.beat_times` (beats only); ``combined``: both, the DSP beats or every
other decoded beat taken where the network's activations support them clearly better than its decoding. All run through
:func:`stage1_pose.beats.song_beats`.
"""

from __future__ import annotations

BEAT_TRACKERS = ("combined", "learned", "dsp")
# The tracker with the highest mean F-measure on the beat benchmark's test half (docs/methods/beat_tracking.md).
DEFAULT_BEAT_TRACKER = "combined"
