"""Figures (matplotlib, headless Agg backend, written as PNG atomically): training curves of run folders and
the stage-1 report's figures."""

from __future__ import annotations

import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen before pyplot is imported)
import numpy as np  # noqa: E402

from dancesynth.core.fileio import atomic_path  # noqa: E402


def _save(fig: plt.Figure, path: str | os.PathLike) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(fig)


def _robust_ylim(ax: plt.Axes, values: np.ndarray) -> None:
    """Scale the y axis to the 99th percentile, so one start-up transient does not flatten the rest."""
    top = float(np.percentile(values, 99)) if len(values) else 0.0
    ax.set_ylim(0.0, 1.15 * top if top > 0 else 1.0)


# Columns of a metrics table that are positions or bookkeeping, not curves.
NOT_CURVES = ("step", "epoch", "seconds")


def plot_metrics(csv_paths: list[str | os.PathLike], path: str | os.PathLike) -> None:
    """One panel per numeric column of the given metrics CSVs (each has a ``step`` column: the x axis).

    Empty cells (a column a training phase does not log) are gaps. Nothing is drawn before the first row.
    """
    curves: list[tuple[str, list[float], list[float]]] = []
    for csv_path in csv_paths:
        if not os.path.isfile(csv_path):
            continue
        with open(csv_path, newline="") as f:
            rows = list(csv.DictReader(f))
        keys = [k for k in (rows[0] if rows else {}) if k not in NOT_CURVES]
        steps = [float(r["step"]) for r in rows]
        curves += [(k, steps, [float(r[k]) if r.get(k) else np.nan for r in rows]) for k in keys]
    if not curves:
        return
    fig, axes = plt.subplots(len(curves), 1, figsize=(6, 2.2 * len(curves)), squeeze=False, sharex=True)
    for ax, (key, steps, values) in zip(axes[:, 0], curves):
        ax.plot(steps, values, lw=0.9)
        ax.set_ylabel(key, fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("step")
    fig.tight_layout()
    _save(fig, path)


def plot_fid_over_time(curves: dict[str, list[float]], window_seconds: float, path: str | os.PathLike) -> None:
    """Long-term FID (Dance Revolution Fig. 4): one line per row, x = window start in seconds."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, curve in curves.items():
        ax.plot(np.arange(len(curve)) * window_seconds, curve, marker="o", ms=3, label=name)
    ax.set_xlabel(f"window start (s), {window_seconds:g}-s windows")
    ax.set_ylabel("FID vs training windows (lower is better)")
    ax.set_title("FID over time")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)


def plot_beat_alignment(onset: np.ndarray, music_beats: np.ndarray, fps: float,
                        dances: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], path: str | os.PathLike,
                        title: str) -> None:
    """Music onset strength and each dance's kinematic offset strength, beats marked (Dancing2Music Fig. 2).

    Args:
        onset: ``[T]`` onset strength per pose frame.
        music_beats: music beat times in seconds (dashed grey lines in every panel).
        dances: row name -> (kinematic offsets ``[T]``, D2M beat frames, velocity-minimum beat frames).
    """
    fig, axes = plt.subplots(len(dances) + 1, 1, figsize=(10, 1.6 * (len(dances) + 1)), sharex=True)
    t = np.arange(len(onset)) / fps
    axes[0].plot(t, onset, color="black", lw=0.8)
    axes[0].set_ylabel("onset", fontsize=8)
    _robust_ylim(axes[0], onset)
    axes[0].set_title(title, fontsize=9)
    for ax, (name, (offsets, d2m, vmin)) in zip(axes[1:], dances.items()):
        n = min(len(offsets), len(t))
        ax.plot(t[:n], offsets[:n], color="tab:blue", lw=0.8)
        d2m, vmin = np.asarray(d2m, int), np.asarray(vmin, int)
        d2m, vmin = d2m[d2m < n], vmin[vmin < n]
        ax.plot(d2m / fps, offsets[d2m], "v", color="tab:red", ms=5, label="D2M kinematic beat")
        ax.plot(vmin / fps, np.zeros(len(vmin)), "|", color="tab:green", ms=10, mew=2, label="velocity minimum")
        ax.set_ylabel(name, fontsize=8, rotation=0, ha="right")
        _robust_ylim(ax, offsets[:n])
    for ax in axes:
        for b in music_beats:
            ax.axvline(b, color="grey", ls="--", lw=0.6)
    axes[1].legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time (s); dashed lines = music beats")
    _save(fig, path)
