"""Shared fixtures: a tiny stage-1 dataset whose audio features are pre-cached, so no test waits for librosa."""

from pathlib import Path

import numpy as np
import pytest
import soundfile

from stage1_pose.audio import feature_dim
from stage1_pose.data.dataset import Clip, clip_paths, create_layout, write_beats, write_manifest
from dancesynth.core.skeleton import PoseSequence

FPS, SR, SECONDS = 15.0, 8000, 8.0


def write_tiny_stage1_dataset(root: Path, splits=("train", "train", "train", "val", "test")) -> Path:
    """Clips of 8 s: a click track at 120 BPM, a body swaying on the beat, random cached features."""
    rng = np.random.default_rng(0)
    create_layout(root)
    frames = int(SECONDS * FPS)
    t = np.arange(frames) / FPS
    base = rng.uniform(-60, 60, (25, 2)) + (640, 360)
    clips = []
    for i, split in enumerate(splits):
        cid = f"clip{i}"
        paths = clip_paths(cid)
        song = np.zeros(int(SECONDS * SR), np.float32)
        for beat in np.arange(0, SECONDS, 0.5):
            k = int(beat * SR)
            song[k:k + 400] += np.sin(np.arange(400) * 0.3) * np.exp(-np.arange(400) / 80)
        soundfile.write(root / paths["audio"], song, SR)
        sway = 40 * np.sin(2 * np.pi * t + i)[:, None, None] * rng.uniform(0.5, 1.5, (1, 25, 1))
        kp = np.concatenate([base + sway, np.ones((frames, 25, 1))], axis=-1)
        PoseSequence(kp, FPS, 1280, 720).save(root / paths["poses"])
        write_beats(root / paths["beats"], np.arange(0, SECONDS, 0.5), np.arange(0, SECONDS, 2.0), 120.0, "exact")
        feats = root / "features" / "dance_revolution"
        feats.mkdir(parents=True, exist_ok=True)
        np.save(feats / f"{cid}.npy", rng.standard_normal((frames, feature_dim("dance_revolution"))).astype(np.float32))
        clips.append(Clip(cid, f"song{i}", "hiphop", split, **paths))
    write_manifest(root, FPS, SR, ["hiphop"], clips)
    return root


@pytest.fixture(scope="session")
def tiny_stage1_dataset(tmp_path_factory) -> Path:
    """Path of a read-only tiny dataset (5 clips of 8 s: 3 train, 1 val, 1 test)."""
    return write_tiny_stage1_dataset(tmp_path_factory.mktemp("tiny_stage1") / "data")
