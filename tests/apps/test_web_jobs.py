"""The web app's job store across a server restart, one server per data folder, and its upload retention (no
browser; the last tests run real `dancesynth serve` processes and a job's worker)."""

import http.client
import json
import logging
import os
import shlex
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import uvicorn
from web_client import FORM, PAGE, call, form, wav

import apps.demo
from apps.cli import build_parser, main
from apps.demo import DemoPlan
from apps.logs import kept_warnings
from apps.requests import DanceRequest
from apps.web.jobs import JobStore, parse_progress
from apps.web.server import create_app
from apps.web.tasks import dance_job, demo_job
from dancesynth.core.errors import DancesynthError
from stage2_video.presets import PRESETS, preset_names


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


class _Ended:
    """A worker process that has ended (what JobStore checks of one)."""

    exitcode = 0

    def is_alive(self) -> bool:
        return False

    def join(self, timeout: float | None = None) -> None:
        return None


@pytest.mark.parametrize("result", [{"outputs": {}, "info": {}}, {"error": "The song is silent."}])
def test_the_warnings_a_worker_logs_are_handed_back_with_its_job(tmp_path, result):
    with kept_warnings() as warnings:
        logging.getLogger("stage2_video.training_data").warning("The target video shows the person's hips rarely.")
        logging.getLogger("stage2_video.training_data").error("an error is the job's error, not a warning")
        logging.getLogger("urllib3").warning("another library's warning stays in the log")
    assert warnings == ["The target video shows the person's hips rarely."]
    store = JobStore(tmp_path, {})
    job = store.create("dance", "a dance", {})
    assert store.get(job["id"])["warnings"] == []
    (tmp_path / "jobs" / job["id"] / "result.json").write_text(json.dumps({**result, "warnings": warnings}))
    store._running = (job["id"], _Ended())
    store._check_running()
    ended = store.get(job["id"])
    assert ended["state"] == ("failed" if "error" in result else "done") and ended["warnings"] == warnings


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
    app = create_app(data, cache, device="cpu", keep_uploads_hours=24.0)
    web = app.state.web
    web.start_cleanup.join(60)
    assert not unused.exists() and fresh.is_dir() and queued.is_dir() and trained.is_dir()

    # With a shorter retention, the next upload's cleanup takes the hour-old one; what a job or a model needs stays.
    web.keep_uploads_hours = 0.5
    status, saved, _ = call(app, "POST", "/api/uploads", FORM, form("song", "song.wav", wav()))
    assert status == 200
    assert not fresh.exists() and queued.is_dir() and trained.is_dir()
    assert sorted(p.name for p in (data / "uploads").iterdir()) == sorted([queued.name, trained.name, saved["id"]])
    web.close()


def test_a_demo_jobs_command_makes_the_call_the_job_makes(tmp_path, monkeypatch):
    """The page's "Equivalent command" of a demo job: `dancesynth demo`, or for a server whose demo plan has other
    sizes (which `dancesynth demo` has no options for) the Python call; run, it calls run_demo as the job does."""
    calls = []

    def run_demo(out, minutes=15.0, seed=0, device="auto", plan=None):
        calls.append((str(out), minutes, seed, device, plan or DemoPlan()))
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
        web.close()


def test_a_job_queued_by_an_older_server_ends_with_a_sentence(tmp_path):
    """A job.json whose request has fields this dancesynth's request has not (or lacks its required ones) fails with
    one sentence, not a TypeError "failed unexpectedly"."""
    older = "^This job was queued by an older dancesynth and cannot run; start it again from the page.$"
    settings = {"data": str(tmp_path)}
    with pytest.raises(DancesynthError, match=older):
        dance_job({"song_path": "song.wav", "out": "dance.mp4", "video_model": "m"}, tmp_path / "out", settings)
    with pytest.raises(DancesynthError, match=older):
        demo_job({"out": str(tmp_path / "demo"), "budget": 2.5}, tmp_path / "demo", settings)
    assert not (tmp_path / "out").exists()


def test_the_commands_of_jobs_at_every_preset_the_page_offers_are_accepted_by_the_cli(tmp_path, monkeypatch):
    """The page's menu offers the registry's presets and auto; the "Equivalent command" of a training and of a
    dance at each of them parses (train-video once refused --preset medium), with auto made a named preset."""
    monkeypatch.chdir(tmp_path)  # the dance command's outputs are relative names
    app = create_app(tmp_path / "data", tmp_path / "cache", device="cpu")
    web = app.state.web
    web.start_cleanup.join(60)
    video = _upload(tmp_path / "data", "e" * 12, hours_old=0).name
    song = call(app, "POST", "/api/uploads", FORM, form("song", "song.wav", wav()))[1]["id"]
    offered = [p["name"] for p in call(app, "GET", "/api/config", PAGE)[1]["presets"]]
    assert offered == list(preset_names(auto=True))
    for preset in offered:
        for body in ({"kind": "train", "video": video, "minutes": 1, "preset": preset},
                     {"kind": "dance", "song": song, "video": video, "minutes": 1, "preset": preset}):
            job = web.create_job(body)
            argv = shlex.split(job["command"])
            assert argv[0] == "dancesynth"
            args = build_parser().parse_args(argv[1:])
            assert args.command == {"train": "train-video", "dance": "dance"}[body["kind"]]
            assert args.preset in PRESETS and (preset == "auto" or args.preset == preset)
            if body["kind"] == "dance":  # the command makes the very request the job runs
                assert DanceRequest.from_namespace(args) == DanceRequest(**job["params"])
    web.close()


def _running_job(data: Path) -> Path:
    """The folder of a job a server is running, with its partial output."""
    job = JobStore(data, {}).create("dance", "a dance", {})
    folder = data / "jobs" / job["id"]
    (folder / "out").mkdir()
    (folder / "out" / "dance.mp4").write_bytes(b"half a video")
    (folder / "job.json").write_text(json.dumps({**job, "state": "running", "pid": os.getpid()}))
    return folder


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_second_server_on_a_data_folder_is_refused_and_changes_nothing(tmp_path):
    data = tmp_path / "data"
    first = create_app(data, tmp_path / "cache", device="cpu")
    first.state.web.start_cleanup.join(60)
    folder = _running_job(data)
    before = _snapshot(data)
    try:
        with pytest.raises(DancesynthError) as refused:
            create_app(data, tmp_path / "cache", device="cpu")
        assert str(refused.value) == (f"Another dancesynth server (process {os.getpid()}) is using the data folder "
                                      f"{data}; stop it first, or give this one another --data.")
        assert _snapshot(data) == before
        assert json.loads((folder / "job.json").read_text())["state"] == "running"
    finally:
        first.state.web.close()
    # Once the first server is gone, the next one takes the folder (and the job it left is interrupted).
    second = create_app(data, tmp_path / "cache", device="cpu")
    second.state.web.start_cleanup.join(60)
    second.state.web.jobs._launch = lambda job: None  # this test runs no worker
    second.state.web.jobs.start()
    second.state.web.close()
    assert json.loads((folder / "job.json").read_text())["state"] == "interrupted"


def test_serve_on_a_data_folder_in_use_exits_1_with_a_sentence_and_changes_nothing(tmp_path, capsys, monkeypatch):
    data = tmp_path / "data"
    first = create_app(data, tmp_path / "cache", device="cpu")
    first.state.web.start_cleanup.join(60)
    folder = _running_job(data)
    before = _snapshot(data)
    monkeypatch.setattr(uvicorn.Server, "run", lambda self, sockets=None: pytest.fail("the second server started"))
    try:
        flags = ["--data", str(data), "--cache", str(tmp_path / "cache"), "--port", str(_free_port())]
        assert main(["serve", *flags]) == 1
    finally:
        first.state.web.close()
    assert capsys.readouterr().err == (f"dancesynth serve: error: Another dancesynth server (process {os.getpid()}) "
                                       f"is using the data folder {data}; stop it first, or give this one another "
                                       "--data.\n")
    assert _snapshot(data) == before and (folder / "out" / "dance.mp4").is_file()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("flags, says", [
    (["--port", "{taken}"], "The server cannot listen on 127.0.0.1:{taken}: port {taken} on 127.0.0.1 is already in "
                            "use (by another `dancesynth serve` or another program); stop that, or choose another "
                            "--port."),
    (["--host", "no-such-host.invalid"], "The host 'no-such-host.invalid' is not an address or a known name"),
    (["--host", "192.0.2.1"], "The server cannot listen on 192.0.2.1:{free}: 192.0.2.1 is not an address of this "
                              "machine"),
    (["--port", "70000"], "dancesynth serve: error: argument --port: must be a port from 1 to 65535, got '70000'"),
])
def test_serve_on_a_port_it_cannot_have_exits_1_with_a_sentence_before_touching_the_data_folder(tmp_path, capsys,
                                                                                                monkeypatch, flags,
                                                                                                says):
    monkeypatch.setattr(uvicorn.Server, "run", lambda self, sockets=None: pytest.fail("the server started"))
    data = tmp_path / "data"
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port, free = taken.getsockname()[1], _free_port()
        flags = [flag.format(taken=port) for flag in flags]
        assert main(["serve", "--data", str(data), *(["--port", str(free)] if "--port" not in flags else []),
                     *flags]) == 1
    err = capsys.readouterr().err
    assert says.format(taken=port, free=free) in err and err.count("\n") == 1 and "Traceback" not in err
    assert not data.exists()


# --- real servers -------------------------------------------------------------------------------------------------
REPO = Path(__file__).parents[2]
SERVER_START_S = 60.0
WORKER_EXIT_S = 30.0  # a worker follows its server in seconds (tasks.ORPHAN_GRACE_S at most); CI may be loaded


def _request(port: int, method: str, path: str, body: dict | None = None) -> tuple[int, dict | list]:
    """(status, JSON answer) of a request of the page to the server at ``port`` (a body goes as JSON)."""
    page = f"127.0.0.1:{port}"
    headers = {"Host": page, "Origin": f"http://{page}", **({"Content-Type": "application/json"} if body else {})}
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        connection.request(method, path, body=json.dumps(body).encode() if body else None, headers=headers)
        response = connection.getresponse()
        return response.status, json.loads(response.read())
    finally:
        connection.close()


def _serve(data: Path, port: int, log: Path) -> subprocess.Popen:
    """`dancesynth serve` on ``data`` at ``port`` (its stderr in ``log``: a worker shares it until it has its own)."""
    with open(log, "a") as err:
        return subprocess.Popen([sys.executable, "-m", "apps.cli", "serve", "--data", str(data), "--cache",
                                 str(data.parent / "cache"), "--port", str(port), "--device", "cpu"], cwd=REPO,
                                stdout=subprocess.DEVNULL, stderr=err, env={**os.environ, "OMP_NUM_THREADS": "1"})


def _started(server: subprocess.Popen, port: int) -> None:
    """Wait for the server to list its jobs (which, unlike the cache, does not wait for torch to load)."""
    deadline = time.monotonic() + SERVER_START_S
    while time.monotonic() < deadline and server.poll() is None:
        try:
            if _request(port, "GET", "/api/jobs")[0] == 200:
                return
        except OSError:
            time.sleep(0.05)
    pytest.fail(f"the server did not start (exit status {server.poll()})")


def _running_demo(port: int) -> dict:
    """A demo job the server at ``port`` has just started running (its worker starting)."""
    status, job = _request(port, "POST", "/api/jobs", {"kind": "demo", "minutes": 2})
    assert status == 200, job
    deadline = time.monotonic() + 30
    while job["state"] == "queued" and time.monotonic() < deadline:
        job = _request(port, "GET", f"/api/jobs/{job['id']}")[1]
    assert job["state"] == "running", job
    return job


def _process_running(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not yet reaped by its new parent, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def _stop(server: subprocess.Popen) -> None:
    """Stop the server as Ctrl-C does."""
    if server.poll() is None:
        server.send_signal(signal.SIGINT)
    try:
        server.wait(30)
    finally:
        server.kill()


def test_a_second_serve_while_the_first_runs_a_job_exits_1_and_changes_nothing(tmp_path):
    data, port, log = tmp_path / "data", _free_port(), tmp_path / "server.log"
    first = _serve(data, port, log)
    try:
        _started(first, port)
        job = _running_demo(port)
        others = {k: v for k, v in _snapshot(data).items() if not k.startswith(f"jobs/{job['id']}/")}
        second = subprocess.run([sys.executable, "-m", "apps.cli", "serve", "--data", str(data), "--port",
                                 str(_free_port())], cwd=REPO, capture_output=True, text=True, timeout=60)
        assert second.returncode == 1 and second.stderr == (
            f"dancesynth serve: error: Another dancesynth server (process {first.pid}) is using the data folder "
            f"{data}; stop it first, or give this one another --data.\n")
        assert {k: v for k, v in _snapshot(data).items() if not k.startswith(f"jobs/{job['id']}/")} == others
        assert _request(port, "GET", f"/api/jobs/{job['id']}")[1]["state"] == "running"
    finally:
        _stop(first)
    assert json.loads((data / "jobs" / job["id"] / "job.json").read_text())["state"] == "interrupted"


def test_a_server_killed_as_its_job_starts_takes_the_worker_with_it_and_a_restart_marks_the_job_interrupted(
        tmp_path):
    data, port, log = tmp_path / "data", _free_port(), tmp_path / "server.log"
    server = _serve(data, port, log)
    try:
        _started(server, port)
        job = _running_demo(port)  # its worker may not have started yet: it must still follow its server
        server.send_signal(signal.SIGKILL)
        server.wait()
    finally:
        server.kill()
    deadline = time.monotonic() + WORKER_EXIT_S
    while _process_running(job["pid"]) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _process_running(job["pid"]), "the job's worker ran on without its server"
    restarted = _serve(data, port, log)
    try:
        _started(restarted, port)
        seen = _request(port, "GET", f"/api/jobs/{job['id']}")[1]
        assert seen["state"] == "interrupted" and seen["error"] == ("The server stopped while this job ran; start "
                                                                    "it again.")
    finally:
        _stop(restarted)
    assert not (data / "jobs" / job["id"] / "out").exists()
    assert [p for p in data.rglob("*") if ".part" in p.name] == []
    assert "Traceback" not in log.read_text()
