"""The built-in paired music + dance dataset: synthetic songs and the dances performed to them.

Clip ``i`` gets style ``STYLES[i % number of styles]`` and its own random stream derived from the seed, so the
dataset is the same for a seed whatever the number of worker processes. Every clip is its own song.
"""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

import numpy as np

from dancesynth.core.errors import DancesynthError
from dancesynth.core.progress import track
from stage1_pose.data.layout import (
    MANIFEST,
    POSE_FPS,
    SAMPLE_RATE,
    Clip,
    clip_paths,
    create_layout,
    split_songs,
    write_audio,
    write_beats,
    write_manifest,
)
from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_dance import synthesize_dance
from stage1_pose.data.synth_music import synthesize_song
from stage1_pose.music_features import num_pose_frames

# Shortest clip: a few beats of the slowest style, and enough frames for the audio features' analysis windows.
MIN_SECONDS = 2.0


def _make_clip(job: tuple[str, int, str, float, np.random.SeedSequence]) -> Clip:
    root, index, style_name, seconds, seed = job
    style = STYLES[style_name]
    rng = np.random.default_rng(seed)
    clip_id = f"{style_name}_{index:05d}"
    paths = clip_paths(clip_id)
    song = synthesize_song(style, seconds, rng)
    frames = num_pose_frames(len(song.samples), song.sample_rate, POSE_FPS)
    dance = synthesize_dance(style, song.beats, frames, rng)
    write_audio(Path(root) / paths["audio"], song.samples, song.sample_rate)
    dance.save(Path(root) / paths["poses"])
    write_beats(Path(root) / paths["beats"], song.beats, song.downbeats, song.tempo, "exact")
    return Clip(id=clip_id, song=clip_id, style=style_name, split="train", **paths)


def make_dataset(out_dir: str | os.PathLike, clips: int = 100, seconds: float = 60.0, seed: int = 0,
                 workers: int = 2, progress: bool = True) -> Path:
    """Generate ``clips`` synthetic songs of ``seconds`` seconds with their dances into the new dataset folder
    ``out_dir`` (layout: :mod:`stage1_pose.data.dataset`), using ``workers`` processes. Returns the manifest path.

    Styles rotate over :data:`stage1_pose.data.styles.STYLES`; songs are split 80/10/10 into train/val/test,
    stratified by style. The same ``seed`` gives the same dataset.
    """
    if clips < 1:
        raise DancesynthError(f"--clips must be at least 1, got {clips}.")
    if not seconds >= MIN_SECONDS:
        raise DancesynthError(f"--seconds must be at least {MIN_SECONDS:g}, got {seconds:g}.")
    if workers < 1:
        raise DancesynthError(f"--workers must be at least 1, got {workers}.")
    root = Path(out_dir)
    if (root / MANIFEST).exists():
        raise DancesynthError(f"{root} already holds a dataset; choose a new folder or delete it first.")
    create_layout(root)
    names = list(STYLES)
    seeds = np.random.SeedSequence(seed).spawn(clips + 1)
    jobs = [(str(root), i, names[i % len(names)], float(seconds), seeds[i]) for i in range(clips)]
    bar = track(total=clips, desc="make-dataset", unit="clip", disable=not progress)
    if workers == 1 or clips == 1:
        made = []
        for job in jobs:
            made.append(_make_clip(job))
            bar.update()
    else:
        # spawn: the parent may have imported torch, whose threads do not survive a fork safely; the workers
        # import only numpy-level modules, so they start quickly
        with multiprocessing.get_context("spawn").Pool(min(workers, clips)) as pool:
            made = []
            for clip in pool.imap(_make_clip, jobs):
                made.append(clip)
                bar.update()
    bar.close()
    by_style = {name: [c.song for c in made if c.style == name] for name in names}
    split = split_songs(by_style, np.random.default_rng(seeds[-1]))
    final = [Clip(**{**c.__dict__, "split": split[c.song]}) for c in made]
    return write_manifest(root, POSE_FPS, SAMPLE_RATE, names, final)
