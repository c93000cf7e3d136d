"""The pose model shipped inside the package, used by `generate` and `dance` when no pose model is given.

``dance_revolution/`` is a weights-only run folder (``latest.json`` + safetensors, no optimizer state):
Dance Revolution's ``small`` preset trained on the built-in dataset (60 songs of 60 s) by
``scripts/build_pose_model.sh``, chosen by ``dancesynth check`` and the stage-1 report (docs/methods/
dance_revolution.md gives its numbers). ``python -m stage1_pose.pretrained RUN`` replaces it with another run.

``beat_tracker/`` holds the learned beat and downbeat tracker's networks, one folder each (``seed0/``, ``seed1/``:
``model.safetensors`` + ``config.json``), trained by ``benchmarks/train_beat_tracker.py`` and averaged by
:mod:`stage1_pose.beat_tracking.tracker` (docs/methods/beat_tracking.md).
"""

from __future__ import annotations

from pathlib import Path

DEFAULT_POSE_MODEL = Path(__file__).with_name("dance_revolution")
# The built-in dataset seed the shipped model learnt (make-dataset's default, as the build script uses it): any
# other seed makes songs it never heard.
TRAINING_DATA_SEED = 0
# Run metadata that names the trainer's machine (the dataset folder) and means nothing to a user of the package.
LOCAL_ENTRIES = ("data",)
