"""Deferred interrupts, each test in a fresh process: a signal sent to the test process itself could land in the
native libraries other tests loaded there (it crashed once OpenVINO and mediapipe had run)."""

import multiprocessing
import os
import signal

from dancesynth.core.interrupts import deferred_interrupts


def _first_asks_second_interrupts() -> None:
    before = signal.getsignal(signal.SIGTERM)
    try:
        with deferred_interrupts() as stop:
            os.kill(os.getpid(), signal.SIGTERM)
            assert stop.requested
            os.kill(os.getpid(), signal.SIGINT)
        os._exit(3)  # the second signal did not interrupt
    except KeyboardInterrupt:
        os._exit(0 if signal.getsignal(signal.SIGTERM) is before else 4)


def _exit_code(target) -> int:
    child = multiprocessing.get_context("spawn").Process(target=target)
    child.start()
    child.join(60)
    return child.exitcode


def test_first_signal_asks_to_stop_second_interrupts_and_handlers_come_back():
    assert _exit_code(_first_asks_second_interrupts) == 0
