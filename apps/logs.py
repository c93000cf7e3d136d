"""How the tool's own messages look and where they go: one setup for the `dancesynth` command (:mod:`apps.cli`,
which maps -q/-v to a level) and the web page's job workers (:mod:`apps.web.tasks`, into each job's log)."""

from __future__ import annotations

import logging
import sys
from typing import TextIO

# The project's top-level packages: their loggers follow -q/-v; other libraries' stay at WARNING.
PACKAGES = ("apps", "dancesynth", "stage1_pose", "stage2_video")


class _Formatter(logging.Formatter):
    """INFO lines as they are; others prefixed by their level (``warning: ...``, ``debug: ...``)."""

    def format(self, record: logging.LogRecord) -> str:
        message = super().format(record)
        return message if record.levelno == logging.INFO else f"{record.levelname.lower()}: {message}"


class _Handler(logging.StreamHandler):
    """The tool's handler (a type of its own so that configuring again replaces it); without a stream of its own
    it writes to whatever ``sys.stderr`` is at the time, so a replaced stderr is followed, not written after close."""

    def __init__(self, stream: TextIO | None) -> None:
        super().__init__(stream)
        self._follow_stderr = stream is None

    def emit(self, record: logging.LogRecord) -> None:
        if self._follow_stderr:
            self.stream = sys.stderr
        super().emit(record)


def configure_logging(level: int, stream: TextIO | None = None) -> None:
    """Show the project's messages from ``level`` up (and other libraries' warnings) on ``stream`` (stderr)."""
    root = logging.getLogger()
    for handler in [h for h in root.handlers if isinstance(h, _Handler)]:
        root.removeHandler(handler)
    handler = _Handler(stream)
    handler.setFormatter(_Formatter())
    root.addHandler(handler)
    for name in PACKAGES:
        logging.getLogger(name).setLevel(level)
