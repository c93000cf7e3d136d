"""Overlapping the stages of a streaming loop: a producer that runs ahead in a thread.

Rendering a video is a chain (network -> compositing -> encoder) whose heavy parts are native code that releases
the GIL (OpenVINO, OpenCV, libx264); running the producing end in a thread lets the encoder work on frame t while
frame t + 1 is computed, instead of each core waiting for the other's half.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")

_DONE = object()


class _Failure:
    def __init__(self, error: BaseException) -> None:
        self.error = error


def read_ahead(iterable: Iterable[T], depth: int = 2) -> Iterator[T]:
    """Yield the items of ``iterable`` in order while a thread computes up to ``depth`` of the next ones.

    An exception raised by ``iterable`` is raised here, at the item where it happened. Closing the returned
    generator early (``break``, an error in the consumer) stops the thread before the next item and waits for it,
    so nothing keeps running behind the caller's back.
    """
    if depth < 1:
        raise ValueError(f"depth must be at least 1, got {depth}")
    items: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in iterable:
                if not _put(items, item, stop):
                    return
            _put(items, _DONE, stop)
        except BaseException as error:  # handed to the consumer, which re-raises it in its own thread
            _put(items, _Failure(error), stop)

    worker = threading.Thread(target=produce, name="dancesynth-read-ahead", daemon=True)
    worker.start()
    try:
        while True:
            item = items.get()
            if item is _DONE:
                return
            if isinstance(item, _Failure):
                raise item.error
            yield item
    finally:
        stop.set()
        # A generator dropped by its own producer (a read-ahead over a read-ahead) is closed in that thread.
        if worker is not threading.current_thread():
            worker.join()


def _put(items: queue.Queue, item: object, stop: threading.Event) -> bool:
    """Put ``item`` unless ``stop`` is set first; False when stopped."""
    while not stop.is_set():
        try:
            items.put(item, timeout=0.1)
            return True
        except queue.Full:
            continue
    return False
