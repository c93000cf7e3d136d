"""The files of a job's folder (laid out in :mod:`apps.web.jobs`), named once for the server's job store and the
worker (:mod:`apps.web.tasks`) that both read and write them."""

from __future__ import annotations

import json
from pathlib import Path

from dancesynth.core.fileio import atomic_path

JOB_FILE = "job.json"
LOG_FILE = "log.txt"
RESULT_FILE = "result.json"
OUT = "out"


def write_json(path: Path, value: dict) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(value, indent=2))
