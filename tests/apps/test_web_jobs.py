"""The web app's job store across a server restart, and its upload retention (no browser, no worker)."""

import io
import json
import os
import shlex
import time
from pathlib import Path

import numpy as np
import soundfile
from fastapi import UploadFile

import apps.demo
from apps.cli import main
from apps.demo import DemoPlan
from apps.web.jobs import JobStore, parse_progress
from apps.web.server import create_app
from apps.web.tasks import demo_job


def test_a_job_left_running_by_a_stopped_server_becomes_interrupted_and_loses_its_partial_outputs(tmp_path):
    store = JobStore(tmp_path, {})
    job = store.create("dance", "a dance", {})
    folder = tmp_path / "jobs" / job["id"]
    (folder / "out").mkdir()
    (folder / "out" / "dance.mp4").write_bytes(b"half a video")
    state = json.loads((folder / "job.json").read_text())
    (folder / "job.json").write_text(json.dumps({**state, "state": "running", "pid": 2**22 + 1}))
    (folder / "log.txt").write_text("rendering: 120/480 frame (25%), 4.0 frame/s, 1m30s left\n")

    restarted = JobStore(tmp_path, {})
    restarted._launch = lambda job: None  # this test runs no worker
    restarted.start()
    try:
        seen = restarted.get(job["id"])
        assert seen["state"] == "interrupted" and "server stopped" in seen["error"]
        assert not (folder / "out").exists()
        assert seen["progress"]["percent"] == 25 and seen["progress"]["left"] == "1m30s"
    finally:
        restarted.stop()


def test_progress_is_the_latest_progress_line():
    log = ("training: 30/600 s (5%), 1.0 s/s, 9m30s left, step=3\nsaved checkpoint\n"
           "rendering: 480/480 frame (100%), 4.0 frame/s, took 2m00s\n")
    p = parse_progress(log)
    assert (p["what"], p["done"], p["total"], p["unit"], p["left"], p["took"]) == \
        ("rendering", 480, 480, "frame", None, "2m00s")
    assert parse_progress("no progress here\n") is None


def _upload(data: Path, upload_id: str, hours_old: float) -> Path:
    """An upload folder as the server leaves it, its upload.json ``hours_old`` hours old."""
    folder = data / "uploads" / upload_id
    folder.mkdir(parents=True)
    (folder / "clip.mp4").write_bytes(b"video")
    (folder / "upload.json").write_text(json.dumps({"id": upload_id, "kind": "video", "name": "clip.mp4"}))
    when = time.time() - hours_old * 3600
    os.utime(folder / "upload.json", (when, when))
    return folder


def test_old_uploads_are_removed_unless_a_queued_job_or_a_cached_model_needs_them(tmp_path):
    data, cache = tmp_path / "data", tmp_path / "cache"
    unused, fresh = _upload(data, "a" * 12, 30), _upload(data, "b" * 12, 1)
    queued, trained = _upload(data, "c" * 12, 30), _upload(data, "d" * 12, 30)
    JobStore(data, {}).create("dance", "a dance", {"target": str(queued / "clip.mp4"), "seed": 0})
    (cache / "0123abcd-small").mkdir(parents=True)
    (cache / "0123abcd-small" / "source.json").write_text(json.dumps({"video": str(trained / "clip.mp4")}))

    # At start: create_app cleans in the background (it starts no job: the app's lifespan does).
    web = create_app(data, cache, device="cpu", keep_uploads_hours=24.0).state.web
    web.start_cleanup.join(60)
    assert not unused.exists() and fresh.is_dir() and queued.is_dir() and trained.is_dir()

    # With a shorter retention, the next upload's cleanup takes the hour-old one; what a job or a model needs stays.
    web.keep_uploads_hours = 0.5
    song = io.BytesIO()
    soundfile.write(song, np.sin(np.arange(16000) / 8000 * 2 * np.pi * 220), 8000, format="WAV")
    song.seek(0)
    saved = web.save_upload(UploadFile(song, filename="song.wav"), "song")
    assert not fresh.exists() and queued.is_dir() and trained.is_dir()
    assert sorted(p.name for p in (data / "uploads").iterdir()) == sorted([queued.name, trained.name, saved["id"]])


def test_a_demo_jobs_command_makes_the_call_the_job_makes(tmp_path, monkeypatch):
    """The page's "Equivalent command" of a demo job: `dancesynth demo`, or for a server whose demo plan has other
    sizes (which `dancesynth demo` has no options for) the Python call; run, it calls run_demo as the job does."""
    calls = []

    def run_demo(out_dir, minutes=15.0, seed=0, device="auto", plan=None):
        calls.append((str(out_dir), minutes, seed, device, plan or DemoPlan()))
        return []

    monkeypatch.setattr(apps.demo, "run_demo", run_demo)
    toy = DemoPlan(clips=6, clip_seconds=12.0, target_seconds=4.0, preset="small")
    for plan, program in ((None, "dancesynth"), (DemoPlan(), "dancesynth"), (toy, "python")):
        web = create_app(tmp_path / "data", tmp_path / "cache", device="cpu", demo=plan).state.web
        web.start_cleanup.join(60)
        job = web.create_job({"kind": "demo", "minutes": 2.5})
        demo_job(job["params"], tmp_path / "out", web.jobs.settings)
        argv = shlex.split(job["command"])
        assert argv[0] == program
        if program == "dancesynth":
            assert main(argv[1:]) == 0
        else:
            exec(argv[2], {})
        assert calls[-1] == calls[-2] == (str(tmp_path / "data" / "demo"), 2.5, 0, "cpu", plan or DemoPlan())
