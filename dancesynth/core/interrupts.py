"""Stopping a long loop cleanly on Ctrl-C or SIGTERM: the first signal asks, the loop stops at a safe point.

A training interrupted in the middle of an optimizer update would save a half-applied step; inside
:func:`deferred_interrupts` the first SIGINT / SIGTERM only sets :attr:`StopRequest.requested`, which the loop
checks between steps, and a second one raises :class:`KeyboardInterrupt` at once (a user who insists). Every
trainer's loop runs inside it through :meth:`dancesynth.core.runs.RunFolder.training`.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from types import FrameType

SIGNALS = (signal.SIGINT, signal.SIGTERM)


@dataclass
class StopRequest:
    """Whether a stop was asked for (set by the first signal)."""

    requested: bool = False


@contextlib.contextmanager
def deferred_interrupts() -> Iterator[StopRequest]:
    """Defer SIGINT / SIGTERM while the block runs (main thread only; in another thread signals keep their
    handlers and the request never turns true). The previous handlers come back afterwards."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        if request.requested:
            raise KeyboardInterrupt
        request.requested = True

    previous = {sig: signal.signal(sig, handler) for sig in SIGNALS}
    try:
        yield request
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
