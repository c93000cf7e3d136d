import logging

from dancesynth.core.progress import track


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _lines(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "dancesynth.core.progress"]


def test_log_lines_at_most_every_interval_with_rate_and_time_left(caplog):
    clock = FakeClock()
    caplog.set_level(logging.INFO)
    done = []
    for i in track(range(100), desc="rendering", unit="frame", interval_s=5.0, clock=clock, tty=False):
        clock.now += 1.0  # one frame per second
        done.append(i)
    assert done == list(range(100))
    lines = _lines(caplog)
    # 100 s of work, one line per 5 s at most, plus the closing line
    assert 19 <= len(lines) <= 21
    assert lines[0] == "rendering: 5/100 frame (5%), 1 frame/s, 1m35s left"
    assert lines[-1].startswith("rendering: 100/100 frame (100%), 1 frame/s, took 1m40s")


def test_manual_updates_with_postfix_and_resumed_count(caplog):
    clock = FakeClock()
    caplog.set_level(logging.INFO)
    with track(total=10, initial=4, desc="epochs", unit="epoch", interval_s=10.0, clock=clock, tty=False) as bar:
        bar.set_postfix(loss="0.125")
        clock.now += 20.0
        bar.update(2)
    first = _lines(caplog)[0]
    assert first == "epochs: 6/10 epoch (60%), 0.1 epoch/s, 40s left, loss=0.125"


def test_short_loop_and_quiet_logging_print_nothing(caplog):
    clock = FakeClock()
    caplog.set_level(logging.INFO)
    assert list(track([1, 2, 3], desc="fast", interval_s=5.0, clock=clock, tty=False)) == [1, 2, 3]
    assert _lines(caplog) == []

    caplog.set_level(logging.WARNING)  # what `dancesynth -q` sets
    for _ in track(range(10), desc="quiet", interval_s=1.0, clock=clock, tty=False):
        clock.now += 5.0
    assert _lines(caplog) == []


def test_terminal_bar_goes_to_stderr_and_counts(caplog, capsys):
    caplog.set_level(logging.INFO)
    bar = track(total=3, desc="bar", unit="clip", tty=True)
    for _ in range(3):
        bar.update()
    bar.close()
    assert bar.n == 3
    err = capsys.readouterr().err
    assert "bar" in err and "3/3" in err
