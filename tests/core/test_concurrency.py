import threading
import time

import pytest

from dancesynth.core.concurrency import read_ahead


def test_items_come_in_order_and_all():
    assert list(read_ahead(iter(range(50)), depth=3)) == list(range(50))


def test_the_producer_runs_ahead_while_the_consumer_works():
    produced = []

    def slow_source():
        for i in range(4):
            produced.append(i)
            yield i

    ahead = read_ahead(slow_source(), depth=2)
    assert next(ahead) == 0
    deadline = time.monotonic() + 5
    while len(produced) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    # Item 0 handed over, items 1 and 2 waiting in the queue: the producer got ahead without being asked.
    assert produced == [0, 1, 2]
    assert list(ahead) == [1, 2, 3]


def test_an_error_in_the_producer_is_raised_in_the_consumer_at_its_item():
    def failing():
        yield 1
        yield 2
        raise OSError("disk gone")

    got = []
    with pytest.raises(OSError, match="disk gone"):
        for item in read_ahead(failing()):
            got.append(item)
    assert got == [1, 2]


def test_stopping_early_stops_the_thread():
    def endless():
        i = 0
        while True:
            yield i
            i += 1

    def read_ahead_threads() -> set[threading.Thread]:
        return {t for t in threading.enumerate() if t.name == "dancesynth-read-ahead"}

    # Another test in the same worker process may leave its own read-ahead thread to the garbage collector.
    before, others = threading.active_count(), read_ahead_threads()
    for item in read_ahead(endless(), depth=2):
        if item == 5:
            break
    assert threading.active_count() <= before
    assert not read_ahead_threads() - others


def test_depth_below_one_is_refused():
    with pytest.raises(ValueError, match="depth"):
        next(read_ahead(iter([1]), depth=0))


def test_closing_from_its_own_producer_thread_does_not_try_to_join_itself():
    """A read-ahead whose generator is dropped by the thread producing its items (a read-ahead over a read-ahead)
    is closed in that thread."""
    held, taken, closed, errors = {}, threading.Event(), threading.Event(), []

    def source():
        yield 1
        taken.wait(5)  # the consumer is out of the generator again, so it may be closed
        try:
            held["ahead"].close()
        except RuntimeError as error:  # "cannot join current thread"
            errors.append(error)
        closed.set()
        yield 2

    held["ahead"] = read_ahead(source())
    assert next(held["ahead"]) == 1
    taken.set()
    assert closed.wait(5)
    assert errors == []
