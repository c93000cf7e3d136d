"""Fixtures of the stage-2 training and rendering tests: a tiny trained run (the tiny target video and config are
in tests/conftest.py, the trainer protocol's test uses them too)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def tiny_run(tiny_target, tiny_config, tmp_path_factory) -> Path:
    """A run folder trained for two steps (enough to have a complete checkpoint) that renders with its network: no
    selection frames, so its two steps are kept even where the warp alone would score better."""
    from stage2_video.train import TrainOptions, train_video
    video, poses = tiny_target
    run = tmp_path_factory.mktemp("run")
    train_video(video, run, "small", TrainOptions(epochs=1, max_steps=2, val_frames=4), poses=poses,
                device="cpu", overrides={**tiny_config, "select_fraction": 0.0})
    return run
