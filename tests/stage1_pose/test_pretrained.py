"""The pose model shipped in the package: small enough to ship, and it dances a song it never heard."""

import json
from pathlib import Path

import numpy as np
import pytest

from dancesynth.core.media import SONG_SAMPLE_RATE, load_song
from dancesynth.core.motion import (
    beats_aligned,
    bone_length_errors,
    chance_hit_rate,
    kinematic_beats,
    mean_speed,
    reference_bone_lengths,
    velocity_minimum_beats,
)
from dancesynth.core.skeleton import body_scale
from stage1_pose.beat_snap import BeatSnap
from stage1_pose.data.dataset import DanceDataset
from stage1_pose.data.make_dataset import make_dataset
from stage1_pose.generate import generate_dance, load_pose_model
from stage1_pose.pretrained import DEFAULT_POSE_MODEL

SECONDS = 30.0


def test_shipped_model_is_weights_and_json_only_and_at_most_20_mb():
    files = [p for p in DEFAULT_POSE_MODEL.rglob("*") if p.is_file()]
    assert {p.suffix for p in files} == {".json", ".safetensors"}
    assert sum(p.stat().st_size for p in files) <= 20 * 2 ** 20


@pytest.mark.parametrize("seed", [0, 1])
def test_shipped_model_dances_an_unheard_song_to_its_end_without_freezing(tmp_path, seed):
    # Dataset seed 7: songs the model (trained on dataset seed 0) never heard.
    make_dataset(tmp_path / "songs", clips=1, seconds=SECONDS, seed=7, workers=1, progress=False)
    dataset = DanceDataset(tmp_path / "songs")
    clip = dataset.clips()[0]
    samples = load_song(dataset.root / clip.audio, SONG_SAMPLE_RATE)
    dance = generate_dance(load_pose_model(DEFAULT_POSE_MODEL, "cpu"), samples, SONG_SAMPLE_RATE, seed=seed)
    assert len(dance) == pytest.approx(SECONDS * dance.fps, abs=2)
    assert np.isfinite(dance.keypoints).all()
    real = dataset.load_poses(clip)
    unit = body_scale(real)
    window = int(10 * dance.fps)
    first, last = (mean_speed(part.xy, dance.fps, unit_length=unit)
                   for part in (dance.slice_frames(0, window), dance.slice_frames(len(dance) - window, len(dance))))
    real_speed = mean_speed(real.xy, real.fps, unit_length=unit)
    # `dancesynth check`'s no-freeze criteria: the last 10 s move at least half as fast as the first 10 s and
    # as half the real dance.
    assert last >= 0.5 * first and last >= 0.5 * real_speed, (first, last, real_speed)
    # One body throughout: no bone strays more than 5 % from its median length (the shipped model places its
    # joints by forward kinematics; Dance Revolution's paper output drifted 49 % at the 99th percentile).
    errors = bone_length_errors(dance.xy, reference_bone_lengths(dance.xy))
    assert np.nanpercentile(errors, 99) <= 0.05


def test_shipped_model_dances_on_the_true_beats_of_a_real_recording():
    # Rock at 135 BPM, beats from its Frets-on-Fire chart; generation tracks its own beats and retimes onto them.
    # With one tracker named, so the bounds test the retiming, not a change of the default tracker.
    song = Path(__file__).parents[1] / "data" / "real_song" / "escape_from_chaosland_40-65s"
    samples = load_song(song.with_suffix(".ogg"), SONG_SAMPLE_RATE)
    true = np.asarray(json.loads(song.with_suffix(".beats.json").read_text())["beats"])
    model = load_pose_model(DEFAULT_POSE_MODEL, "cpu")
    over_chance = {}
    for name, snap in (("retimed", BeatSnap()), ("no accent", BeatSnap(accent=0.0)), ("own timing", None)):
        dance = generate_dance(model, samples, SONG_SAMPLE_RATE, seed=0, snap=snap, tracker="dsp")
        for definition, detect in (("stops", velocity_minimum_beats), ("d2m", kinematic_beats)):
            moves = detect(dance.xy, dance.fps)
            hit = beats_aligned(moves, true * dance.fps, 1).mean()
            chance = chance_hit_rate(moves, true * dance.fps, len(dance), np.random.default_rng(0), tolerance_frames=1)
            over_chance[name, definition] = hit - chance
    # Share of movement beats within one frame of a true beat, over chance: the retiming is what puts the stops
    # there, and its accent what puts Dancing2Music's kinematic beats (motion lost per frame) there too.
    assert over_chance["retimed", "stops"] >= 0.5 > over_chance["own timing", "stops"], over_chance  # 0.63, 0.30
    assert over_chance["retimed", "d2m"] >= 0.35 > over_chance["no accent", "d2m"], over_chance  # 0.43, 0.08
