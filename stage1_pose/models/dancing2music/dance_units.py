"""Dancing2Music dance units and the beat warper (Lee et al. 2019, Sec. 3.1 and 3.3).

A dance unit is a 32-frame snippet whose 4 kinematic beats sit at the fixed unit frames 0, 8, 16 and 24: the
span from one kinematic beat to the fifth one after it is resampled with a piecewise-linear time warp, one
linear piece per beat interval. Consecutive units therefore tile a dance on a regular beat grid (unit frame
32 would be the next unit's frame 0), which is what lets the beat warper at test time place every unit beat
on a beat of the song.

Positions are fractional pose-frame indices throughout (not seconds); arrays are sampled by linear
interpolation between neighbouring frames.
"""

from __future__ import annotations

import numpy as np

from dancesynth.core.errors import DancesynthError

UNIT_FRAMES = 32
BEATS_PER_UNIT = 4
BEAT_SPACING = UNIT_FRAMES // BEATS_PER_UNIT
BEAT_POSITIONS: tuple[int, ...] = tuple(range(0, UNIT_FRAMES, BEAT_SPACING))


def sample_frames(x: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``x`` (``[T, ...]``, one row per frame) at fractional frame ``positions``.

    Positions outside ``[0, T - 1]`` are clamped to the first / last frame. Returns ``[N, ...]``.
    """
    x = np.asarray(x)
    positions = np.clip(np.asarray(positions, dtype=np.float64), 0.0, len(x) - 1)
    lo = np.floor(positions).astype(np.int64)
    hi = np.minimum(lo + 1, len(x) - 1)
    w = (positions - lo).reshape((-1,) + (1,) * (x.ndim - 1))
    return ((1.0 - w) * x[lo] + w * x[hi]).astype(x.dtype, copy=False)


def sample_frames_smooth(x: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Catmull-Rom interpolation of ``x`` (``[T, ...]``) at fractional frame ``positions``, ``[N, ...]``.

    Unlike :func:`sample_frames` the velocity stays continuous across source frames: resampling with linear
    pieces makes the speed jump at every source frame, and those jumps read as kinematic beats of their own
    when a dance is slowed down. Positions outside ``[0, T - 1]`` are clamped.
    """
    x = np.asarray(x)
    if len(x) < 2:
        return sample_frames(x, positions)
    last = len(x) - 1
    positions = np.clip(np.asarray(positions, dtype=np.float64), 0.0, last)
    # Straight-line ghost frames before the first and after the last keep the end velocities.
    padded = np.concatenate([2 * x[:1] - x[1:2], x, 2 * x[-1:] - x[-2:-1]])
    i1 = np.minimum(np.floor(positions).astype(np.int64), last - 1)
    shape = (-1,) + (1,) * (x.ndim - 1)
    t = (positions - i1).reshape(shape)
    p0, p1, p2, p3 = padded[i1], padded[i1 + 1], padded[i1 + 2], padded[i1 + 3]
    out = p1 + 0.5 * t * ((p2 - p0) + t * ((2 * p0 - 5 * p1 + 4 * p2 - p3) + t * (3 * (p1 - p2) + p3 - p0)))
    return out.astype(x.dtype, copy=False)


def unit_positions(beat_frames: np.ndarray) -> np.ndarray:
    """Source frame positions ``[32]`` of a unit spanning 5 consecutive kinematic beats (frame indices).

    Unit frame ``8k + j`` (``0 <= j < 8``) maps to ``b_k + j / 8 * (b_{k+1} - b_k)``, so the unit's beats land on
    frames 0, 8, 16, 24 and the fifth beat is where the next unit starts.
    """
    beat_frames = np.asarray(beat_frames, dtype=np.float64)
    if beat_frames.shape != (BEATS_PER_UNIT + 1,):
        raise ValueError(f"a unit needs {BEATS_PER_UNIT + 1} beat frames, got shape {beat_frames.shape}")
    knots = np.arange(BEATS_PER_UNIT + 1) * BEAT_SPACING
    return np.interp(np.arange(UNIT_FRAMES), knots, beat_frames)


def unit_runs(beats: np.ndarray, min_gap: float, max_gap: float) -> list[np.ndarray]:
    """Group kinematic beats into runs of consecutive, non-overlapping units.

    Args:
        beats: increasing kinematic beat frame indices ``[K]``.
        min_gap, max_gap: allowed beat interval in frames; a longer or shorter interval ends a run (the dancer
            paused, or the detector fired twice on one movement).

    Returns:
        one ``[n, 5]`` array of beat frames per run with at least one unit; unit ``i + 1`` starts at the beat
        where unit ``i`` ends.
    """
    beats = np.asarray(beats, dtype=np.float64)
    if len(beats) < BEATS_PER_UNIT + 1:
        return []
    gaps = np.diff(beats)
    ok = (gaps >= min_gap) & (gaps <= max_gap)
    runs: list[np.ndarray] = []
    start = 0
    for end in list(np.flatnonzero(~ok)) + [len(gaps)]:
        # Gaps start..end-1 are valid, so beats start..end form one run.
        n = (end - start) // BEATS_PER_UNIT
        if n > 0:
            idx = start + np.arange(n)[:, None] * BEATS_PER_UNIT + np.arange(BEATS_PER_UNIT + 1)[None]
            runs.append(beats[idx])
        start = end + 1
    return runs


def cut_units(x: np.ndarray, unit_beats: np.ndarray) -> np.ndarray:
    """Time-normalised units ``[n, 32, ...]`` of a per-frame array ``x`` ``[T, ...]`` (poses or audio features).

    ``unit_beats`` is ``[n, 5]`` beat frames (a run from :func:`unit_runs`).
    """
    return np.stack([sample_frames(x, unit_positions(b)) for b in np.asarray(unit_beats)])


def beat_grid(music_beats: np.ndarray, num_frames: int, stride: float = 1) -> np.ndarray:
    """Frame positions of the dance beats for a song of ``num_frames`` frames: ``[K]`` increasing.

    ``stride`` is music beats per dance beat. From 1 up, every ``round(stride)``-th music beat (fractional frame
    indices) is a dance beat, as dancers need not move on every musical beat; below 1, every music beat interval
    is split into ``round(1 / stride)`` equal dance beats (moving on the half beats, as dancers who move faster
    than the music's pulse do). The grid is extended before the first and after the last beat with the median
    dance beat interval so it covers frames ``0 .. num_frames - 1``.
    """
    beats = np.asarray(music_beats, dtype=np.float64)
    if stride >= 1:
        beats = beats[::max(1, int(round(stride)))]
    else:
        parts = int(round(1 / stride))
        beats = np.append(beats[:-1, None] + np.diff(beats)[:, None] * np.arange(parts) / parts, beats[-1])
    if len(beats) < 2:
        raise DancesynthError("The song has fewer than two beats to dance to; use a song with a steady rhythm "
                              "of at least a few seconds.")
    interval = float(np.median(np.diff(beats)))
    n_before = int(np.ceil(beats[0] / interval)) if beats[0] > 0 else 0
    last = num_frames - 1
    n_after = int(np.ceil((last - beats[-1]) / interval)) if beats[-1] < last else 0
    before = beats[0] - interval * np.arange(n_before, 0, -1)
    after = beats[-1] + interval * np.arange(1, n_after + 1)
    return np.concatenate([before, beats, after])


def beat_stride(music_beats: np.ndarray, dance_interval: float) -> float:
    """Music beats per dance beat, so the dance beats come about every ``dance_interval`` frames (the typical
    kinematic beat interval seen in training): the whole number ``n`` of music beats per dance beat when the dance
    is slower than the music's pulse, ``1 / n`` (dancing on the ``n``-th parts of a beat) when it is faster (a unit,
    four dance beats, then lasts about as long as it did in training, instead of being stretched over four music
    beats). ``n`` is the nearest in ratio (a tempo 1.45x off is nearer 2x than 1x), so the warper plays the units
    at most sqrt(2)x faster or slower than they were learnt."""
    beats = np.asarray(music_beats, dtype=np.float64)
    if len(beats) < 2:
        return 1.0
    ratio = dance_interval / float(np.median(np.diff(beats)))
    return float(_nearest_in_ratio(ratio)) if ratio >= 1 else 1.0 / _nearest_in_ratio(1.0 / ratio)


def _nearest_in_ratio(ratio: float) -> int:
    """The whole number ``n >= 1`` nearest ``ratio`` (>= 1) in ratio: ``n`` or ``n + 1``, split at their geometric
    mean."""
    n = max(1, int(np.floor(ratio)))
    return n if ratio <= np.sqrt(n * (n + 1)) else n + 1


def units_needed(grid: np.ndarray) -> int:
    """Units to generate so that :func:`warp_units` can fill every frame between the grid's first and last beat."""
    return int(np.ceil((len(grid) - 1) / BEATS_PER_UNIT))


def align_beats(kinematic: np.ndarray, num_beats: int, max_stretch: float, margin: float = 1.5) -> np.ndarray:
    """Positions ``[num_beats]`` in the concatenated generated units (unit frames) to put on the song's dance
    beats, so that the units' kinematic beats land on music beats.

    A decoded unit moves with its kinematic beats near, not exactly at, the normalised frames ``8k``, and now
    and then between them. Dynamic programming picks one anchor per dance beat, each either a ``kinematic`` beat
    (frame indices of the concatenated units, :func:`dancesynth.core.motion.kinematic_beats`) or the
    normalised frame, within one beat interval (8 frames) of ``8k``, minimising the kinematic beats left more than
    ``margin`` unit frames inside a beat interval (the warper would put them between music beats). Consecutive
    anchors stay between ``8 / max_stretch`` and ``8 * max_stretch`` frames apart, which bounds how much the
    warper speeds up or slows down the units; ties go to anchors on kinematic beats and even tempo.
    ``max_stretch`` 1 returns the normalised frames ``0, 8, 16, ...``.
    """
    if max_stretch < 1:
        raise ValueError(f"max_stretch must be at least 1, got {max_stretch}")
    nominal = np.arange(num_beats) * float(BEAT_SPACING)
    kinematic = np.unique(np.asarray(kinematic, dtype=np.float64))
    if max_stretch == 1 or len(kinematic) == 0 or num_beats < 2:
        return nominal
    lo, hi = BEAT_SPACING / max_stretch, BEAT_SPACING * max_stretch
    candidates, node_costs = [], []
    for centre in nominal:
        near = kinematic[np.abs(kinematic - centre) <= BEAT_SPACING]
        candidates.append(np.concatenate([[centre], near]))
        node_costs.append(np.concatenate([[0.1], np.zeros(len(near))]))
    cost = node_costs[0]
    back = []
    for k in range(1, num_beats):
        a, b = candidates[k - 1][:, None], candidates[k][None, :]
        length = b - a
        interior = (np.searchsorted(kinematic, b - margin, side="left")
                    - np.searchsorted(kinematic, a + margin, side="right")).clip(min=0)
        step = interior + 0.05 * np.abs(np.log(np.maximum(length, 1e-9) / BEAT_SPACING))
        step = np.where((length >= lo) & (length <= hi), step, np.inf)
        total = cost[:, None] + step
        back.append(total.argmin(axis=0))
        cost = total.min(axis=0) + node_costs[k]
    path = [int(cost.argmin())]
    for pointers in reversed(back):
        path.append(int(pointers[path[-1]]))
    return np.array([candidates[k][i] for k, i in enumerate(reversed(path))])


def warp_units(units: np.ndarray, grid: np.ndarray, num_frames: int,
               unit_beats: np.ndarray | None = None, accent: float = 0.0) -> np.ndarray:
    """The beat warper: lay generated units on the song's beat grid, ``[num_frames, ...]``.

    Args:
        units: ``[n, 32, ...]`` consecutive units; n must be at least :func:`units_needed` of ``grid``.
        grid: dance beat frame positions from :func:`beat_grid`.
        num_frames: output length in frames.
        unit_beats: ``[len(grid)]`` increasing positions of the units' beats in frames of the concatenated units
            (:func:`align_beats`); by default the normalised frames ``0, 8, 16, ...``.
        accent: in ``[0, 1)``; how much the units slow down right after each beat and speed up into the next.

    Output frame ``f`` shows unit-sequence position ``q(f)`` with ``q(grid[k]) = unit_beats[k]``: the units'
    k-th beat lands on ``grid[k]``, stretched or compressed in between. At a fraction ``tau`` of a beat interval
    ``q`` has covered ``tau + accent * tau * (tau - 1)`` of it: piecewise linear for ``accent`` 0 (the paper's
    warper); otherwise the speed falls from ``1 + accent`` to ``1 - accent`` times the interval's mean speed at
    every beat, so the body decelerates on the music beat, which is what a kinematic beat is.
    """
    if not 0 <= accent < 1:
        raise ValueError(f"accent must be in [0, 1), got {accent}")
    units = np.asarray(units)
    if units.shape[0] < units_needed(grid):
        raise ValueError(f"{units_needed(grid)} units are needed for this beat grid, got {units.shape[0]}")
    if unit_beats is None:
        unit_beats = np.arange(len(grid)) * float(BEAT_SPACING)
    unit_beats = np.asarray(unit_beats, dtype=np.float64)
    if len(unit_beats) != len(grid) or np.any(np.diff(unit_beats) <= 0):
        raise ValueError(f"unit_beats must be {len(grid)} increasing positions, got {unit_beats}")
    flat = units.reshape((-1,) + units.shape[2:])
    frames = np.arange(num_frames, dtype=np.float64)
    k = np.clip(np.searchsorted(grid, frames, side="right") - 1, 0, len(grid) - 2)
    tau = np.clip((frames - grid[k]) / (grid[k + 1] - grid[k]), 0.0, 1.0)
    tau = tau + accent * tau * (tau - 1.0)
    q = unit_beats[k] + (unit_beats[k + 1] - unit_beats[k]) * tau
    return sample_frames_smooth(flat, q)

