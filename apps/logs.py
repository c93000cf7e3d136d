"""How the tool's own messages look and where they go: one setup for the `dancesynth` command (:mod:`apps.cli`,
which maps -q/-v to a level) and the web page's job workers (:mod:`apps.web.tasks`, into each job's log)."""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Iterator
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


class _Warnings(logging.Handler):
    """Keeps the text of the tool's own warnings (not errors: a job reports its error apart)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno == logging.WARNING and record.name.split(".")[0] in PACKAGES:
            self.messages.append(record.getMessage())


@contextlib.contextmanager
def kept_warnings() -> Iterator[list[str]]:
    """The list, filled while inside, of the warnings the project's packages log (a web job hands them to the page
    beside its outputs: "the target video hides the person's hips", which the terminal shows as they come)."""
    handler = _Warnings()
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        yield handler.messages
    finally:
        root.removeHandler(handler)
