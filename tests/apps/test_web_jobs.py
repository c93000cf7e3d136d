"""The web app's job store across a server restart (no browser, no worker)."""

import json

from apps.web.jobs import JobStore, parse_progress


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
