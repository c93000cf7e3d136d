"""The pose model shipped in the package: small enough to ship, and it dances a song it never heard."""

import numpy as np
import pytest

from dancesynth.core.media import SONG_SAMPLE_RATE, load_song
from dancesynth.core.motion import bone_length_errors, mean_speed, reference_bone_lengths
from dancesynth.core.skeleton import body_scale
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
