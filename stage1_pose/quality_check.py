"""Quality check of a trained stage-1 run on held-out songs: does it freeze, do seeds differ, is it on the beat.

For each of the first ``clips`` held-out (test, then val) clips of the run's dataset, a dance of ``seconds`` is
generated with every seed from the song's cached features and beats, and measured beside the clip's real dance
(speeds in pixels per second of the canvas, distances in pixels; the measures are :mod:`dancesynth.core.motion`'s).
Each generated dance gets three verdicts:

* no freeze: its mean joint speed over the last 10 s is at least half that over the first 10 s, and at least
  half the real held-out dances' mean speed;
* seeds differ: its distance to the nearest dance of another seed (mean over joints and frames) is at least 10 %
  of the distance between two real dances of one style, the scale of "another dance"; distances are also split
  into body (joints relative to the MidHip) and root (where the dancer stands), since real dancers differ most
  in where they stand;
* beats: its beat hit rate (kinematic beats within 2 frames of a music beat) beats chance, the hit rate of the
  same kinematic beats shifted by random offsets, by 0.10.

The mean joint speed by beat phase (tenths of the interval from one music beat to the next) is reported with
them: real dances slow down on the beat.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.motion import (
    DanceDistance,
    chance_hit_rate,
    dance_distance,
    kinematic_beats,
    mean_speed,
    speed_by_beat_phase,
)
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.generate import generate_from_features, load_pose_model
from stage1_pose.metrics import beat_hit_rate

WINDOW_SECONDS = 10.0  # the first and last stretch of a dance compared for freezing
MIN_SPEED_SHARE = 0.5  # last-window speed vs first-window speed and vs the real dances' mean speed
MIN_SEED_GAP_SHARE = 0.1  # seed gap vs the gap between two real dances of one style
MIN_HITS_OVER_CHANCE = 0.1
PHASE_BINS = 10


@dataclass(frozen=True)
class CheckOptions:
    """What to check: ``clips`` held-out clips, the first ``seconds`` of each song, one dance per seed
    (at least two seeds); generation on ``device`` at ``precision`` (see :func:`stage1_pose.generate.load_pose_model`);
    ``chance_shifts`` random offsets per chance hit rate."""

    clips: int = 3
    seconds: float = 60.0
    seeds: tuple[int, ...] = (0, 1)
    device: str = "auto"
    precision: str = "auto"
    chance_shifts: int = 500

    def __post_init__(self) -> None:
        if self.clips < 1 or not self.seconds > 0:
            raise DancesynthError(f"Check at least one clip for a positive time, got {self.clips} clips of "
                                  f"{self.seconds} s.")
        if len(set(self.seeds)) < 2:
            raise DancesynthError(f"Seeds {list(self.seeds)} cannot show whether seeds differ; give at least two "
                                  "different seeds.")


@dataclass(frozen=True)
class DanceRow:
    """Measures of one dance of a clip; speeds in pixels per second, ``speed_by_phase`` ``[PHASE_BINS]``.
    ``seed_gap``: a generated dance's distance (pixels) to the nearest dance of another seed, None for the real one."""

    clip: str
    dance: str  # "real" or "seed N"
    speed_first: float
    speed_last: float
    kinematic_beats: int
    hit_rate: float
    chance: float
    speed_by_phase: tuple[float, ...]
    seed_gap: DanceDistance | None = None


@dataclass(frozen=True)
class Verdict:
    """The three criteria of one generated dance."""

    clip: str
    dance: str
    no_freeze: bool
    seeds_differ: bool
    beats: bool

    @property
    def passed(self) -> bool:
        """All three criteria met."""
        return self.no_freeze and self.seeds_differ and self.beats


@dataclass(frozen=True)
class CheckResult:
    """A check's measures: ``real_speed`` (pixels per second) and ``real_pair_gap`` (pixels) are the references
    the verdicts compare with."""

    real_speed: float
    real_pair_gap: DanceDistance
    rows: list[DanceRow]
    verdicts: list[Verdict]
    run: dict[str, Any]  # run folder, method, epoch

    def to_json(self) -> dict[str, Any]:
        """Plain JSON values (NaN -> None), verdicts with their ``passed``."""
        out = asdict(self)
        out["real_pair_gap"] = self.real_pair_gap._asdict()
        for row, raw in zip(out["rows"], self.rows):
            row["seed_gap"] = raw.seed_gap._asdict() if raw.seed_gap is not None else None
        for verdict, raw in zip(out["verdicts"], self.verdicts):
            verdict["passed"] = raw.passed
        return _finite(out)


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def no_freeze(speed_first: float, speed_last: float, real_speed: float) -> bool:
    """The dance keeps moving: last-window speed >= half the first window's and >= half the real dances' mean."""
    return speed_last >= MIN_SPEED_SHARE * speed_first and speed_last >= MIN_SPEED_SHARE * real_speed


def seeds_differ(seed_gap: float, real_pair_gap: float) -> bool:
    """Another seed gives another dance: the gap is >= 10 % of two real dances' (False without a real pair)."""
    return bool(seed_gap >= MIN_SEED_GAP_SHARE * real_pair_gap)


def on_beat(hit_rate: float, chance: float) -> bool:
    """Kinematic beats hit the music beats more often than chance by 0.10 (False without kinematic beats)."""
    return bool(hit_rate > chance + MIN_HITS_OVER_CHANCE)


def measure_dance(clip: str, name: str, xy: np.ndarray, music_frames: np.ndarray, fps: float,
                  rng: np.random.Generator, shifts: int = 500) -> DanceRow:
    """:class:`DanceRow` (without seed gap) of ``[T, 25, 2]`` pixel positions against music beats in pose frames."""
    window = int(WINDOW_SECONDS * fps)
    kin = kinematic_beats(xy, fps)
    return DanceRow(clip, name, mean_speed(xy[:window], fps), mean_speed(xy[-window:], fps), len(kin),
                    beat_hit_rate(kin, music_frames), chance_hit_rate(kin, music_frames, len(xy), rng, shifts),
                    tuple(speed_by_beat_phase(xy, music_frames, fps, PHASE_BINS).tolist()))


def check_clip(clip: str, real_xy: np.ndarray, dances: dict[int, np.ndarray], music_frames: np.ndarray, fps: float,
               real_speed: float, real_pair_gap: DanceDistance, rng: np.random.Generator,
               shifts: int = 500) -> tuple[list[DanceRow], list[Verdict]]:
    """Rows (the real dance first, then one per seed) and verdicts (one per seed) of one clip.

    Args:
        real_xy: ``[T, 25, 2]`` the clip's real dance in pixels.
        dances: seed -> ``[T, 25, 2]`` generated dance in pixels (at least two seeds).
        music_frames: the song's beats in fractional pose frames (seconds x fps).
        real_speed: mean joint speed (pixels per second) of the real held-out dances.
        real_pair_gap: distance between two real dances of one style.
    """
    if len(dances) < 2:
        raise DancesynthError("Seeds can only be compared with at least two dances per clip; give two seeds.")
    rows, verdicts = [measure_dance(clip, "real", real_xy, music_frames, fps, rng, shifts)], []
    for seed, xy in dances.items():
        gap = min((dance_distance(xy, other) for s, other in dances.items() if s != seed), key=lambda d: d.joints)
        row = measure_dance(clip, f"seed {seed}", xy, music_frames, fps, rng, shifts)
        rows.append(replace(row, seed_gap=gap))
        verdicts.append(Verdict(clip, row.dance, no_freeze(row.speed_first, row.speed_last, real_speed),
                                seeds_differ(gap.joints, real_pair_gap.joints), on_beat(row.hit_rate, row.chance)))
    return rows, verdicts


def real_pair_gap(dances: list[tuple[str, np.ndarray]]) -> DanceDistance:
    """Mean :func:`dance_distance` over all pairs of ``(style, [T, 25, 2] pixels)`` real dances of one style;
    NaN when no two share a style."""
    found = [dance_distance(a, b) for i, (style_a, a) in enumerate(dances) for style_b, b in dances[i + 1:]
             if style_a == style_b]
    return DanceDistance(*np.mean(found, axis=0).tolist()) if found else DanceDistance(*[float("nan")] * 3)


def check_run(run_dir: str | os.PathLike, data_dir: str | os.PathLike | None = None,
              options: CheckOptions | None = None) -> CheckResult:
    """Generate and judge dances of a stage-1 run for the first ``options.clips`` held-out clips of ``data_dir``
    (default: the dataset the run was trained on).

    The dances are generated from the dataset's cached features of each song (computed once per song, not per
    seed) and its beats, as :mod:`stage1_pose.evaluate` does.
    """
    options = options or CheckOptions()
    model = load_pose_model(run_dir, options.device, options.precision)
    data = DanceDataset(data_dir or model.meta["data"])
    if model.fps != data.fps:
        raise DancesynthError(f"{run_dir} makes dances at {model.fps:g} fps but {data.root} holds {data.fps:g} fps "
                              "dances; check it on a dataset of its own frame rate (--data).")
    held_out = data.clips("test") + data.clips("val")
    if not held_out:
        raise DancesynthError(f"{data.root} has no test or val clips to check on; make the dataset with held-out "
                              "songs.")
    fps, frames_wanted = data.fps, int(options.seconds * data.fps)
    every = data.clips("train") + held_out
    real = {c.id: data.load_poses(c).xy for c in every}
    real_speed = float(np.mean([mean_speed(real[c.id], fps) for c in held_out]))
    pair_gap = real_pair_gap([(c.style, real[c.id][:frames_wanted]) for c in every])
    rng = np.random.default_rng(0)
    all_rows, all_verdicts = [], []
    for clip in held_out[:options.clips]:
        features = np.asarray(data.load_features(clip, model.feature_kind)[:frames_wanted])
        frames = min(len(features), len(real[clip.id]))
        beats = data.load_beats(clip)["beats"]
        beats = beats[beats < frames / fps]
        dances = {s: generate_from_features(model, features[:frames], beats, seed=s).xy
                  for s in dict.fromkeys(options.seeds)}
        rows, verdicts = check_clip(clip.id, real[clip.id][:frames], dances, beats * fps, fps, real_speed, pair_gap,
                                    rng, options.chance_shifts)
        all_rows += rows
        all_verdicts += verdicts
    return CheckResult(real_speed, pair_gap, all_rows, all_verdicts,
                       {"dir": str(run_dir), "method": model.meta.get("method"), "epoch": model.meta.get("epoch")})


def report_text(result: CheckResult) -> str:
    """The check as text: references, a table of measures per dance, speed by beat phase, verdicts."""
    gap = result.real_pair_gap
    lines = [f"run {result.run.get('dir')} ({result.run.get('method')}, epoch {result.run.get('epoch')}); real "
             f"held-out mean speed {result.real_speed:.1f} px/s; two real dances of one style differ by "
             f"{gap.joints:.1f} px on average (body {gap.body:.1f}, root {gap.root:.1f})",
             f"{'clip':<16}{'dance':<8}{'speed first 10s':>16}{'speed last 10s':>15}{'last/first':>11}"
             f"{'vs real':>8}{'kin beats':>10}{'hit rate':>9}{'chance':>8}{'seed gap px (body, root)':>26}"]
    for r in result.rows:
        seed_gap = (f"{r.seed_gap.joints:12.1f} ({r.seed_gap.body:.1f}, {r.seed_gap.root:.1f})"
                    if r.seed_gap is not None else "")
        first, last, real = (max(v, 1e-9) for v in (r.speed_first, r.speed_last, result.real_speed))
        lines.append(f"{r.clip:<16}{r.dance:<8}{r.speed_first:16.1f}{r.speed_last:15.1f}{last / first:11.2f}"
                     f"{last / real:8.2f}{r.kinematic_beats:10d}{r.hit_rate:9.2f}{r.chance:8.2f}{seed_gap}")
    lines += ["", "mean joint speed (px/s) by beat phase, tenths of the interval from one music beat to the next:"]
    lines += [f"{r.clip:<16}{r.dance:<8}" + "".join(f"{v:6.0f}" for v in r.speed_by_phase) for r in result.rows]
    lines.append("")

    def mark(ok: bool) -> str:
        return "PASS" if ok else "FAIL"

    for v in result.verdicts:
        lines.append(f"{v.clip} {v.dance}: no freeze {mark(v.no_freeze)}, beats above chance "
                     f"(+{MIN_HITS_OVER_CHANCE:.2f}) {mark(v.beats)}, seeds differ (>= {MIN_SEED_GAP_SHARE:.0%} of a "
                     f"real pair) {mark(v.seeds_differ)}")
    passed = sum(v.passed for v in result.verdicts)
    lines.append(f"{passed} of {len(result.verdicts)} dances pass all three criteria")
    return "\n".join(lines)
