"""Progress of long loops: a tqdm bar on a terminal, otherwise a log line every few seconds.

Progress is reported on the ``dancesynth.core.progress`` logger at INFO, so ``dancesynth -q`` (or any logging
setup above INFO) silences bars and lines alike, and a library user sees progress only after configuring
logging. A log line reads ``rendering: 120/480 frame (25%), 4.0 frame/s, 1m30s left``.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, Generic, TypeVar

logger = logging.getLogger(__name__)
T = TypeVar("T")

# Seconds between log lines when stderr is not a terminal (a log file, CI output, a pipe).
LOG_INTERVAL_S = 10.0


def _duration(seconds: float) -> str:
    """``75`` -> ``1m15s``; ``3725`` -> ``1h02m``."""
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600}h{s % 3600 // 60:02d}m"
    if s >= 60:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s}s"


class Progress(Generic[T]):
    """Counts work done; iterate over it, or call :meth:`update` by hand. Use :func:`track` to make one.

    Keeps the subset of tqdm's interface the project uses: iteration, ``update``, ``set_postfix``, ``close``
    and use as a context manager.
    """

    def __init__(self, iterable: Iterable[T] | None, total: int | None, desc: str, unit: str, initial: int,
                 interval_s: float, clock: Callable[[], float], bar: Any | None) -> None:
        self._iterable = iterable
        self.total = total
        self.desc = desc
        self.unit = unit
        self.n = initial
        self._initial = initial
        self._interval_s = interval_s
        self._clock = clock
        self._bar = bar
        self._postfix = ""
        self._start = clock()
        self._last_line = self._start
        self._closed = False

    def __iter__(self) -> Iterator[T]:
        if self._iterable is None:
            raise TypeError("this progress counter wraps no iterable; call update() instead")
        try:
            for item in self._iterable:
                yield item
                self.update()
        finally:
            self.close()

    def __enter__(self) -> Progress[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def update(self, n: int = 1) -> None:
        """Count ``n`` more units done."""
        self.n += n
        if self._bar is not None:
            self._bar.update(n)
            return
        now = self._clock()
        if now - self._last_line >= self._interval_s and logger.isEnabledFor(logging.INFO):
            self._last_line = now
            logger.info(self._line(now))

    def set_postfix(self, values: dict[str, Any] | None = None, **kwargs: Any) -> None:
        """Show ``key=value`` pairs (e.g. the latest losses) after the counts."""
        pairs = {**(values or {}), **kwargs}
        if self._bar is not None:
            self._bar.set_postfix(pairs)
        self._postfix = ", ".join(f"{k}={v}" for k, v in pairs.items())

    def close(self) -> None:
        """End the bar; in log mode, a last line when the loop ran long enough to have logged before."""
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()
        elif self._last_line > self._start and logger.isEnabledFor(logging.INFO):
            logger.info(self._line(self._clock(), finished=True))

    def _line(self, now: float, finished: bool = False) -> str:
        elapsed = now - self._start
        done = self.n - self._initial
        rate = done / elapsed if elapsed > 0 else 0.0
        counts = f"{self.n}/{self.total}" if self.total else f"{self.n}"
        parts = [f"{self.desc}: {counts} {self.unit}"]
        if self.total:
            parts[0] += f" ({self.n / self.total:.0%})"
        parts.append(f"{rate:.3g} {self.unit}/s")
        if finished:
            parts.append(f"took {_duration(elapsed)}")
        elif self.total and rate > 0:
            parts.append(f"{_duration((self.total - self.n) / rate)} left")
        if self._postfix:
            parts.append(self._postfix)
        return ", ".join(parts)


def track(iterable: Iterable[T] | None = None, *, total: int | None = None, desc: str = "", unit: str = "it",
             initial: int = 0, disable: bool = False, leave: bool = True, interval_s: float | None = None,
             clock: Callable[[], float] = time.monotonic, tty: bool | None = None) -> Progress[T]:
    """Report progress over ``iterable`` (or over ``update`` calls when it is None).

    Args:
        total: units in all; defaults to ``len(iterable)`` when it has one.
        desc: what is being done, e.g. ``"rendering"``.
        unit: what one step is, e.g. ``"frame"``.
        initial: units already done (a resumed loop).
        disable: report nothing (e.g. on non-zero ranks of a multi-process run).
        leave: keep the finished bar on the terminal.
        interval_s: at most one log line per this many seconds when not on a terminal (default
            :data:`LOG_INTERVAL_S`, read at each call so a process such as the web worker can shorten it).
        clock: seconds, monotonic (tests pass a fake one).
        tty: draw a bar (True) or log lines (False); default: whether stderr is a terminal.
    """
    if total is None and iterable is not None and hasattr(iterable, "__len__"):
        total = len(iterable)  # type: ignore[arg-type]
    quiet = disable or not logger.isEnabledFor(logging.INFO)
    interval_s = LOG_INTERVAL_S if interval_s is None else interval_s
    bar = None
    if tty if tty is not None else sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=total, desc=desc, unit=unit, initial=initial, leave=leave, disable=quiet, file=sys.stderr)
    elif quiet:
        interval_s = float("inf")
    return Progress(iterable, total, desc, unit, initial, interval_s, clock, bar)
