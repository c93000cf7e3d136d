"""The stage-1 quality check's verdicts on constructed dances whose answers are known."""

import json

import numpy as np
import pytest

from dancesynth.core.errors import DancesynthError
from dancesynth.core.motion import DanceDistance, mean_speed
from stage1_pose.quality_check import CheckOptions, CheckResult, check_clip, report_text

FPS = 15.0
FRAMES = int(30 * FPS)
BEATS = np.arange(0, FRAMES, 15.0)  # one music beat a second
REAL_GAP = DanceDistance(100.0, 30.0, 90.0)


def swing_dance(seed: int, beats: np.ndarray = BEATS, amplitude: float = 60.0) -> np.ndarray:
    """``[FRAMES, 25, 2]`` pixels: every joint swings to one side and back, easing in and out so that it stands
    still exactly on each of ``beats`` (a velocity minimum and a turn there); ``seed`` varies the body and moves."""
    rng = np.random.default_rng(seed)
    t = np.arange(FRAMES, dtype=np.float64)
    k = np.clip(np.searchsorted(beats, t, side="right") - 1, 0, len(beats) - 2)
    phase = np.clip((t - beats[k]) / (beats[k + 1] - beats[k]), 0.0, 1.0)
    eased = (1 - np.cos(np.pi * phase)) / 2
    sweep = np.where(k % 2 == 0, eased, 1 - eased)  # there on one interval, back on the next
    body = rng.uniform(-80, 80, (25, 2)) + (640, 360)
    direction = rng.normal(size=(25, 2))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    return body + amplitude * sweep[:, None, None] * direction


def judge(dances: dict[int, np.ndarray]):
    """Rows and verdicts (by dance name) of ``dances`` beside a real dance that stands still on every beat."""
    real = swing_dance(99)
    rows, verdicts = check_clip("song", real, dances, BEATS, FPS, mean_speed(real, FPS), REAL_GAP,
                                np.random.default_rng(0), 100)
    return rows, {v.dance: v for v in verdicts}


def test_two_lively_dances_on_the_beat_pass_every_criterion():
    rows, verdicts = judge({0: swing_dance(0), 1: swing_dance(1)})
    assert [r.dance for r in rows] == ["real", "seed 0", "seed 1"]
    assert all(v.passed for v in verdicts.values()), verdicts
    assert rows[0].seed_gap is None and rows[1].seed_gap == rows[2].seed_gap and rows[1].seed_gap.joints > 10
    # The dances stand still on the beat: the first tenth of each beat interval is the slowest.
    profile = np.array(rows[1].speed_by_phase)
    assert profile.shape == (10,) and profile[0] < 0.2 * profile.max()


def test_a_dance_that_freezes_fails_no_freeze_only():
    frozen = swing_dance(0)
    frozen[-int(12 * FPS):] = frozen[-int(12 * FPS)]
    _, verdicts = judge({0: frozen, 1: swing_dance(1)})
    assert not verdicts["seed 0"].no_freeze and verdicts["seed 1"].no_freeze
    assert verdicts["seed 0"].seeds_differ
    # A dance at a tenth of the real dances' speed fails too, though it never slows down.
    _, slow = judge({0: swing_dance(0, amplitude=6.0), 1: swing_dance(1)})
    assert not slow["seed 0"].no_freeze and slow["seed 0"].beats


def test_identical_seeds_fail_seeds_differ():
    dance = swing_dance(0)
    rows, verdicts = judge({0: dance, 1: dance.copy()})
    assert rows[1].seed_gap == DanceDistance(0.0, 0.0, 0.0)
    assert not verdicts["seed 0"].seeds_differ and not verdicts["seed 1"].seeds_differ
    assert verdicts["seed 0"].no_freeze and verdicts["seed 0"].beats


def test_only_velocity_minima_on_the_music_beats_pass_beats():
    off_beat = swing_dance(1, beats=BEATS + 7.5)  # stands still half-way between two music beats
    rows, verdicts = judge({0: swing_dance(0), 1: off_beat})
    assert verdicts["seed 0"].beats and rows[1].hit_rate > 0.9 and 0 < rows[1].chance < 0.6
    assert not verdicts["seed 1"].beats


def test_options_need_two_different_seeds():
    with pytest.raises(DancesynthError, match="two"):
        CheckOptions(seeds=(3, 3))
    with pytest.raises(DancesynthError, match="two"):
        check_clip("song", swing_dance(0), {0: swing_dance(0)}, BEATS, FPS, 1.0, REAL_GAP, np.random.default_rng(0))


def test_result_reads_as_a_table_and_as_json_with_a_verdict_per_criterion():
    rows, verdicts = judge({0: swing_dance(0), 1: swing_dance(0)})
    result = CheckResult(50.0, DanceDistance(np.nan, np.nan, np.nan), rows, list(verdicts.values()), {"dir": "r"})
    text = report_text(result)
    assert "song            seed 1" in text and "seeds differ (>= 10% of a real pair) FAIL" in text
    assert "0 of 2 dances pass all three criteria" in text
    data = json.loads(json.dumps(result.to_json(), allow_nan=False))
    assert data["real_pair_gap"] == {"joints": None, "body": None, "root": None}
    assert data["rows"][1]["seed_gap"]["joints"] == 0.0 and len(data["rows"][1]["speed_by_phase"]) == 10
    assert [v["passed"] for v in data["verdicts"]] == [False, False]
