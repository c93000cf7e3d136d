"""Fault campaign: real `dancesynth` processes under concurrency, kill -9, a full disk, a read-only disk, and the
web server under a second server, kill -9 and forged requests.

    python benchmarks/fault_campaign.py [--kills 6] [--writers 3] [--work DIR] [--no-server]

Cases (each trial runs the CLI as a subprocess, so nothing is shared with this script):

* two writers: two `generate` processes write the same pose file and preview video at once; both must exit 0
  and leave one complete, valid file of each (the last rename wins) and no temporary file;
* kill -9 while saving: `train-pose --method lstm --checkpoint-every 1` killed at a random moment after its
  first checkpoint; `--resume` must finish the run and `generate` must load it, every time, leaving exactly one
  checkpoint folder and no temporary file;
* disk full: commands writing onto a tmpfs of 2 MB that is already full must exit 1 with one error line and
  leave the disk as it was (needs root to mount; skipped with the reason otherwise); once space is freed, the
  `--resume` that failed must succeed with a clean metrics table;
* read-only: the same tmpfs remounted read-only, including `--resume` of a run stored on it.

Server cases (skipped with `--no-server`), each on a `dancesynth serve --data D` of its own, with the page's
smallest job: a 2-s dance of an uploaded song by a tiny cached appearance model and the tiny LSTM run, posted
through the HTTP API with the page's headers (Host, Origin, `Content-Type: application/json`):

* two servers, one data folder: while the first server runs that job, `serve` on the same `--data` at another
  port, and at the first one's port, must each exit 1 with one error line (naming the first server's process, or
  the port in use) and change nothing in D outside the running job's folder; the job must then finish with its
  outputs;
* kill -9 of the server mid-job (`--kills` trials, the first right as the job starts running, the others at a
  random moment of it): the job's worker must end with its server; `serve` restarted on D must start, list the
  job as interrupted without its partial outputs, leave no temporary file in D or the cache, and run a new job
  to completion;
* forged requests: a foreign `Origin` or `Referer`, none at all, a foreign `Host` (DNS rebinding), job requests
  typed `text/plain` or as a form, JSON over the 64 KB limit (declared, and chunked without a length), 100,000
  nested lists (chunked) and 30,000 (within the limit), ids that are numbers, lists or null, an unknown job kind
  or field: each must be a 4xx whose body is `{"error": sentence}`, within 10 s, and must start no job (jobs
  counted through the API before and after); the server must still answer afterwards, with no traceback in its
  log. The row's note gives the slowest answer's time.

A tiny dataset (`make-dataset --clips 6 --seconds 10`) and LSTM runs keep it to a few minutes on one CPU core.
It prints one row per case: trials run, trials passed, tracebacks seen, leftovers found.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import hashlib
import http.client
import json
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from apps.web.server import API, CONFIG_ROUTE, JOBS_ROUTE, UPLOADS_ROUTE  # noqa: E402
from dancesynth.core.media import probe_video  # noqa: E402
from dancesynth.core.skeleton import PoseSequence  # noqa: E402
from stage2_video.synthetic_person import appearance_preset, write_person_video  # noqa: E402

# The page's HTTP API: URL paths on the server under test, as the server defines them.
JOBS, UPLOADS, CONFIG = (API + route for route in (JOBS_ROUTE, UPLOADS_ROUTE, CONFIG_ROUTE))
LSTM = ["--method", "lstm", "--preview-every", "0", "--device", "cpu", "--set", "hidden=8",
        "--set", "window_frames=30", "--batch-size", "4"]
# The tiniest appearance model (32x32 px, one block, one epoch): what the server's dance jobs render with.
TINY_VIDEO = ["--size", "32x32", "--epochs", "1", "--device", "cpu", "--set", "ngf=4", "--set", "n_blocks=1",
              "--set", "ndf=4", "--set", "n_downsample=1", "--set", "num_d=1", "--set", "batch_size=8"]
POSE_RUN = "lstm"  # the tiny LSTM run's id on the server: its folder under --pose-models
BOUNDARY = "faultcampaignboundary"
SERVER_START_S = 120.0  # a server's start on a busy machine, its cleanup importing torch beside it
JOB_S = 300.0  # the 2-s dance job, its worker importing torch
# A worker notices its server is gone within a second, then cleans up as on Ctrl-C; the 2-s dance takes longer,
# so a worker that outlives this ran on without its server.
WORKER_EXIT_S = 5.0


@dataclass
class Tally:
    """One row of the table."""

    case: str
    ran: int = 0
    passed: int = 0
    tracebacks: int = 0
    leftovers: int = 0
    note: str = ""

    def add(self, ok: bool, errors: list[str], leftovers: list[str]) -> None:
        self.ran += 1
        self.tracebacks += sum("Traceback" in err for err in errors)
        self.leftovers += len(leftovers)
        self.passed += int(ok and not leftovers and not any("Traceback" in err for err in errors))
        if leftovers:
            print(f"  leftovers in {self.case}: {leftovers}", flush=True)


def cli(*args: str, wait: bool = True, log: Path | None = None) -> subprocess.CompletedProcess | subprocess.Popen:
    """Run `dancesynth ARGS` in a fresh interpreter (or start it when not ``wait``, its stderr into the file ``log``
    when given, its stdout dropped)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    command = [sys.executable, "-m", "apps.cli", *args]
    if log is not None:
        with open(log, "w") as err:
            return subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=err, text=True, env=env)
    if not wait:
        return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    return subprocess.run(command, capture_output=True, text=True, env=env)


def one_error_line(done: subprocess.CompletedProcess) -> bool:
    """Exit 1 with exactly one `dancesynth CMD: error:` line, the last thing on stderr."""
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    return done.returncode == 1 and bool(lines) and sum("error:" in line for line in lines) == 1 \
        and "error:" in lines[-1] and "Traceback" not in done.stderr


def temporaries(folder: Path) -> list[str]:
    return [str(p) for p in folder.rglob("*") if ".part" in p.name]


def listing(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): (p.stat().st_size if p.is_file() else -1) for p in folder.rglob("*")}


def two_writers(work: Path, run: Path, song: Path, trials: int) -> Tally:
    tally = Tally("two writers, one output")
    out = work / "writers"
    out.mkdir()
    for trial in range(trials):
        procs = [cli("generate", str(song), "--model", str(run), "--out", str(out / "same.npz"), "--preview",
                     str(out / "same.mp4"), "--seed", str(seed), "--device", "cpu", wait=False) for seed in (1, 2)]
        results = [proc.communicate() for proc in procs]
        errors = [err for _, err in results]
        ok = all(proc.returncode == 0 for proc in procs)
        try:
            poses = PoseSequence.load(out / "same.npz")
            ok = ok and probe_video(out / "same.mp4").num_frames == len(poses) > 0
        except Exception as e:  # a corrupt file is what this case looks for
            print(f"  trial {trial}: output unreadable: {e}", flush=True)
            ok = False
        tally.add(ok, errors, temporaries(out))
    return tally


def kill_during_saves(work: Path, data: Path, song: Path, kills: int, rng: random.Random) -> Tally:
    tally = Tally("kill -9 while checkpointing")
    for trial in range(kills):
        run = work / f"killed_{trial}"
        proc = cli("train-pose", *LSTM, "--data", str(data), "--out", str(run), "--epochs", "3",
                   "--checkpoint-every", "1", wait=False)
        while not (run / "latest.json").exists() and proc.poll() is None:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 1.5))
        finished_first = proc.poll() is not None
        proc.send_signal(signal.SIGKILL)
        _, err = proc.communicate()
        resumed = cli("train-pose", *LSTM, "--data", str(data), "--out", str(run), "--epochs", "3", "--resume")
        generated = cli("generate", str(song), "--model", str(run), "--out", str(work / f"killed_{trial}.npz"),
                        "--device", "cpu")
        checkpoints = [p.name for p in run.iterdir() if p.name.startswith("ckpt-")]
        leftovers = temporaries(run) + (checkpoints[1:] if len(checkpoints) > 1 else [])
        ok = resumed.returncode == 0 and generated.returncode == 0
        if not ok:
            print(f"  trial {trial}: resume {resumed.returncode} {resumed.stderr.strip()[-300:]} | generate "
                  f"{generated.returncode} {generated.stderr.strip()[-300:]}", flush=True)
        if finished_first:
            tally.note = "some trainings finished before the kill"
        tally.add(ok, [err, resumed.stderr, generated.stderr], leftovers)
    return tally


def mount_small_disk(folder: Path) -> str:
    """Mount a 2 MB tmpfs on ``folder``; returns why not ('' when mounted)."""
    folder.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return "needs root and mount(8)"
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(folder)], capture_output=True,
                          text=True)
    return "" if done.returncode == 0 else f"mount failed: {done.stderr.strip()}"


def fill(folder: Path) -> None:
    """Write a filler file until ``folder``'s file system is full."""
    with open(folder / "filler", "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"x" * 4096)
        except OSError:
            pass


def refused_cleanly(tally: Tally, disk: Path, commands: list[list[str]], may_grow: str = "") -> None:
    """Each command must fail with one error line and leave ``disk`` as it was (except the file ``may_grow``)."""
    for args in commands:
        before = listing(disk)
        done = cli(*args)
        after = listing(disk)
        changed = sorted({name for name, _ in set(after.items()) ^ set(before.items())} - {may_grow})
        if not one_error_line(done):
            print(f"  {' '.join(args[:1])}: exit {done.returncode}: {done.stderr.strip()[-400:]}", flush=True)
        tally.add(one_error_line(done), [done.stderr], changed)


def full_and_read_only(work: Path, data: Path, run: Path, song: Path) -> list[Tally]:
    full, read_only = Tally("disk full"), Tally("read-only output")
    disk = work / "disk"
    why = mount_small_disk(disk)
    if why:
        full.note = read_only.note = f"skipped: {why}"
        return [full, read_only]
    try:
        shutil.copytree(run, disk / "run")
        fill(disk)
        writes = [["generate", str(song), "--model", str(run), "--out", str(disk / "p.npz"), "--device", "cpu"],
                  ["generate", str(song), "--model", str(run), "--out", str(work / "ok.npz"), "--preview",
                   str(disk / "p.mp4"), "--device", "cpu"],
                  ["make-dataset", "--out", str(disk / "ds"), "--clips", "2", "--seconds", "4", "--workers", "1"],
                  ["train-pose", *LSTM, "--data", str(data), "--out", str(disk / "new_run"), "--epochs", "1"],
                  ["train-pose", *LSTM, "--data", str(data), "--out", str(disk / "run"), "--epochs", "4",
                   "--resume"]]
        # A resumed run logs each epoch before its checkpoint fails; the next --resume drops those rows (checked).
        refused_cleanly(full, disk, writes, may_grow="run/metrics.csv")
        (disk / "filler").unlink()
        resumed = cli("train-pose", *LSTM, "--data", str(data), "--out", str(disk / "run"), "--epochs", "4",
                      "--resume")
        with open(disk / "run" / "metrics.csv", newline="") as f:
            epochs = [int(row["epoch"]) for row in csv.DictReader(f)]
        full.add(resumed.returncode == 0 and epochs == list(range(4)), [resumed.stderr], temporaries(disk))
        done = subprocess.run(["mount", "-o", "remount,ro", str(disk)], capture_output=True, text=True)
        if done.returncode != 0:
            read_only.note = f"skipped: remount read-only failed: {done.stderr.strip()}"
            return [full, read_only]
        refused_cleanly(read_only, disk, writes + [["extract-poses", str(song), "--out", str(disk / "p.npz")]])
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False)
    return [full, read_only]


# --- the web server ------------------------------------------------------------------------------------------
def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def page_headers(port: int, json_body: bool = False) -> dict[str, str]:
    """The headers the page's requests carry: its Host and Origin (and the JSON type of a job request)."""
    own = f"127.0.0.1:{port}"
    return {"Host": own, "Origin": f"http://{own}", **({"Content-Type": "application/json"} if json_body else {})}


def request(port: int, method: str, path: str, headers: dict[str, str],
            body: bytes | Iterable[bytes] = b"") -> tuple[int, object]:
    """(status, parsed JSON answer or the raw bytes) of one HTTP request to the server at ``port``; a ``body``
    given as chunks goes chunked, without a length. A server that stops reading a refused body may reset the
    connection while it is sent: its answer is still read."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    try:
        with contextlib.suppress(BrokenPipeError, ConnectionResetError):
            connection.request(method, path, body=body, headers=headers, encode_chunked=not isinstance(body, bytes))
        response = connection.getresponse()
        answer = response.read()
    finally:
        connection.close()
    with contextlib.suppress(ValueError):
        return response.status, json.loads(answer)
    return response.status, answer


def api(port: int, method: str, path: str, body: object = None) -> tuple[int, object]:
    """A request of the page: GET, or POST of ``body`` as JSON."""
    data = b"" if body is None else json.dumps(body).encode()
    return request(port, method, path, page_headers(port, json_body=body is not None), data)


@dataclass
class Server:
    """A `dancesynth serve` process, its port and the file its stderr goes to (not a pipe: a job's worker holds the
    server's stderr until it opens its own log, and would keep a reader of a pipe waiting)."""

    process: subprocess.Popen
    port: int
    log: Path

    def stderr(self) -> str:
        return self.log.read_text()


def start_server(work: Path, data: Path, port: int) -> Server:
    """`dancesynth serve` on ``data`` at ``port``, with the campaign's cache and pose models, on the CPU."""
    log = work / f"{data.name}.{port}.{time.monotonic_ns()}.log"
    process = cli("serve", "--data", str(data), "--cache", str(work / "cache"), "--pose-models",
                  str(work / "pose_models"), "--port", str(port), "--device", "cpu", wait=False, log=log)
    return Server(process, port, log)


def wait_ready(server: Server) -> bool:
    """Whether the server lists its jobs before it exits or :data:`SERVER_START_S` pass."""
    deadline = time.monotonic() + SERVER_START_S
    while time.monotonic() < deadline and server.process.poll() is None:
        with contextlib.suppress(OSError, http.client.HTTPException):
            if api(server.port, "GET", JOBS)[0] == 200:
                return True
        time.sleep(0.1)
    return False


def stop_server(server: Server) -> str:
    """Stop the server as Ctrl-C does (kill it when it takes over a minute); its stderr."""
    if server.process.poll() is None:
        server.process.send_signal(signal.SIGINT)
    try:
        server.process.wait(timeout=60)
    except subprocess.TimeoutExpired:
        server.process.kill()
        server.process.wait()
        return server.stderr() + "\n(killed: it did not stop within a minute of Ctrl-C)"
    return server.stderr()


@contextlib.contextmanager
def running_server(work: Path, data: Path, port: int, errors: list[str]) -> Iterator[Server]:
    """A started server, stopped after; its stderr goes to ``errors`` (a server that does not start raises)."""
    server = start_server(work, data, port)
    try:
        if not wait_ready(server):
            raise RuntimeError(f"the server on {data} did not start: {server.stderr().strip()[-300:]}")
        yield server
    finally:
        errors.append(stop_server(server))


def end_orphan(pid: int | None) -> list[str]:
    """A leftover naming the job's worker ``pid`` when it still runs without its server, which is then ended."""
    if not pid or not process_running(pid):
        return []
    os.kill(pid, signal.SIGKILL)
    return [f"worker {pid} still running {WORKER_EXIT_S:g} s after its server was gone"]


def broken_off(case: str, run: Callable[[], Tally]) -> Tally:
    """``run``'s row, or a failed row saying why when a server did not start or refused the page's own request."""
    try:
        return run()
    except (RuntimeError, OSError, http.client.HTTPException) as e:
        print(f"  {case}: broken off: {e}", flush=True)
        return Tally(case, ran=1, note=f"broken off: {str(e)[:100]}")


def upload_song(port: int, song: Path) -> str:
    """Upload ``song`` as the page does (a multipart form: kind, then file); its upload id."""
    head = (f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="kind"\r\n\r\nsong\r\n--{BOUNDARY}\r\n'
            f'Content-Disposition: form-data; name="file"; filename="{song.name}"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n").encode()
    body = head + song.read_bytes() + f"\r\n--{BOUNDARY}--\r\n".encode()
    headers = {**page_headers(port), "Content-Type": f"multipart/form-data; boundary={BOUNDARY}",
               "X-File-Name": song.name}
    status, answer = request(port, "POST", UPLOADS, headers, body)
    if status != 200:
        raise RuntimeError(f"the song upload was refused ({status}): {answer}")
    return answer["id"]


def dance_job(song_id: str, model: str) -> dict:
    """The page's dance request for the smallest dance: 2 s, the tiny models."""
    return {"kind": "dance", "song": song_id, "model": model, "pose_model": POSE_RUN, "start": "0",
            "duration": "2", "seed": "0"}


def start_job(port: int, body: dict) -> dict:
    status, job = api(port, "POST", JOBS, body)
    if status != 200:
        raise RuntimeError(f"the job was refused ({status}): {job}")
    return job


def wait_job(port: int, job_id: str, states: tuple[str, ...], timeout: float = JOB_S) -> dict:
    """The job once its state is one of ``states`` (or as it is when ``timeout`` seconds have passed)."""
    deadline = time.monotonic() + timeout
    while True:
        job = api(port, "GET", f"{JOBS}/{job_id}")[1]
        if job["state"] in states or time.monotonic() > deadline:
            return job
        time.sleep(0.05)


def job_done(port: int, data: Path, job: dict) -> bool:
    """Whether the job finished and each of its outputs is a non-empty file the server hands out."""
    if job["state"] != "done" or not job["outputs"]:
        print(f"  job {job['id']}: {job['state']}: {job.get('error')}", flush=True)
        return False
    for name, path in job["outputs"].items():
        status, _ = request(port, "GET", f"{JOBS}/{job['id']}/files/{name}", page_headers(port))
        if status != 200 or not (data / path).is_file() or (data / path).stat().st_size == 0:
            print(f"  job {job['id']}: output {name} missing ({status})", flush=True)
            return False
    return True


def process_running(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not reaped by its new parent, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def tiny_appearance_model(work: Path, data: Path) -> str:
    """A 3-s synthetic person and their tiniest appearance model, trained into the campaign's cache as `dance
    --target` would cache it; the model's name on the server."""
    seq = PoseSequence.load(sorted((data / "poses").iterdir())[0]).slice_frames(0, 45)
    scale = 64 / seq.height
    seq = PoseSequence(seq.keypoints * (scale, scale, 1), seq.fps, round(seq.width * scale), 64)
    seq.save(work / "person.npz")
    video = work / "person.mp4"
    write_person_video(seq, video, appearance_preset("red_tee"))
    digest = hashlib.sha256(video.read_bytes()).hexdigest()
    entry = work / "cache" / f"{digest[:24]}-small"
    done = cli("train-video", str(video), "--out", str(entry), "--poses", str(work / "person.npz"), *TINY_VIDEO, "-q")
    if done.returncode != 0:
        sys.exit(f"setup failed: train-video: {done.stderr}")
    (entry / "source.json").write_text(json.dumps({"video_sha256": digest, "video": str(video), "preset": "small"}))
    return entry.name


def two_servers(work: Path, song: Path, model: str) -> Tally:
    tally = Tally("two servers, one --data")
    data, port, errors = work / "web_two", free_port(), []
    with running_server(work, data, port, errors) as first:
        job = start_job(port, dance_job(upload_song(port, song), model))
        job = wait_job(port, job["id"], ("running", "done", "failed", "cancelled", "interrupted"))
        if job["state"] != "running":
            tally.note = f"the job was {job['state']} before the second server started"
        own = f"jobs/{job['id']}"
        for other_port, says in ((free_port(), f"Another dancesynth server (process {first.process.pid}) is using "
                                               f"the data folder {data}"),
                                 (port, f"port {port} on 127.0.0.1 is already in use")):
            before = {k: v for k, v in listing(data).items() if not k.startswith(own)}
            second = start_server(work, data, other_port)
            try:
                second.process.wait(timeout=SERVER_START_S)
                err = second.stderr()
            except subprocess.TimeoutExpired:
                err = stop_server(second) + "\n(it was still running: stopped)"
            after = {k: v for k, v in listing(data).items() if not k.startswith(own)}
            changed = sorted({name for name, _ in set(after.items()) ^ set(before.items())})
            done = subprocess.CompletedProcess(second.process.args, second.process.returncode, "", err)
            ok = one_error_line(done) and says in err
            if not ok:
                print(f"  second server on port {other_port}: exit {second.process.returncode}: "
                      f"{err.strip()[-400:]}", flush=True)
            tally.add(ok, [err], changed)
        job = wait_job(port, job["id"], ("done", "failed", "cancelled", "interrupted"))
        finished = job_done(port, data, job)
    tally.add(finished, errors, temporaries(data))
    return tally


def kill_server_mid_job(work: Path, song: Path, model: str, kills: int, rng: random.Random) -> Tally:
    tally = Tally("kill -9 of the server mid-job")
    early = 0
    for trial in range(kills):
        data, port, errors = work / f"web_killed_{trial}", free_port(), []
        server = start_server(work, data, port)
        if not wait_ready(server):
            raise RuntimeError(f"the server on {data} did not start: {server.stderr().strip()[-300:]}")
        song_id = upload_song(port, song)
        job = wait_job(port, start_job(port, dance_job(song_id, model))["id"],
                       ("running", "done", "failed", "cancelled", "interrupted"))
        # The first kill lands as the worker starts, before it may know its server; the others at any moment.
        time.sleep(0.0 if trial == 0 else rng.uniform(0.5, 4.0))
        early += not (data / "jobs" / job["id"] / "log.txt").exists()
        server.process.send_signal(signal.SIGKILL)
        server.process.wait()
        errors.append(server.stderr())
        deadline = time.monotonic() + WORKER_EXIT_S
        while job.get("pid") and process_running(job["pid"]) and time.monotonic() < deadline:
            time.sleep(0.1)
        leftovers = end_orphan(job.get("pid"))
        with running_server(work, data, port, errors):
            killed = api(port, "GET", f"{JOBS}/{job['id']}")[1]
            again = wait_job(port, start_job(port, dance_job(song_id, model))["id"],
                             ("done", "failed", "cancelled", "interrupted"))
            ok = killed["state"] in ("interrupted", "done", "failed") and job_done(port, data, again)
            if killed["state"] == "interrupted" and (data / "jobs" / job["id"] / "out").exists():
                leftovers.append(f"{data}/jobs/{job['id']}/out")
        if not ok:
            print(f"  trial {trial}: the killed job is {killed['state']}; the new one {again['state']}", flush=True)
        leftovers += temporaries(data) + temporaries(work / "cache")
        leftovers += end_orphan(again.get("pid"))
        tally.add(ok, errors, leftovers)
    tally.note = f"{early} of {kills} kills before the worker had started its job"
    return tally


def forged_requests(port: int, song_id: str, model: str) -> list[tuple[str, str, str, dict, bytes | list, int]]:
    """(what, method, path, headers, body, status expected) of each forged or malformed request."""
    own, page, typed = f"127.0.0.1:{port}", page_headers(port), page_headers(port, json_body=True)
    job = json.dumps(dance_job(song_id, model)).encode()

    def body(value: object) -> bytes:
        return json.dumps(value).encode()

    return [
        ("foreign Origin", "POST", JOBS, {**typed, "Origin": "http://evil.example"}, job, 403),
        ("foreign Referer", "POST", JOBS, {"Host": own, "Content-Type": "application/json",
                                                  "Referer": "http://evil.example/page.html"}, job, 403),
        ("no Origin", "POST", JOBS, {"Host": own, "Content-Type": "application/json"}, job, 403),
        ("Origin of another port", "POST", JOBS, {**typed, "Origin": f"http://127.0.0.1:{port + 1}"}, job,
         403),
        ("foreign Host, GET", "GET", JOBS, {"Host": f"evil.example:{port}"}, b"", 403),
        ("foreign Host, POST", "POST", JOBS, {**typed, "Host": f"evil.example:{port}",
                                                     "Origin": f"http://evil.example:{port}"}, job, 403),
        ("foreign cancel", "POST", f"{JOBS}/20250101-000000-abcdef/cancel",
         {**typed, "Origin": "http://evil.example"}, b"", 403),
        ("foreign upload", "POST", UPLOADS, {**page, "Origin": "http://evil.example",
                                                    "Content-Type": f"multipart/form-data; boundary={BOUNDARY}"},
         f"--{BOUNDARY}--\r\n".encode(), 403),
        ("text/plain job", "POST", JOBS, {**page, "Content-Type": "text/plain"}, job, 415),
        ("form-typed job", "POST", JOBS, {**page, "Content-Type": "application/x-www-form-urlencoded"}, job,
         415),
        ("JSON over 64 KB", "POST", JOBS, typed, body({**dance_job(song_id, model), "pad": "x" * 70_000}),
         413),
        ("JSON over 64 KB, chunked", "POST", JOBS, typed, [b" " * 65536 for _ in range(16)], 413),
        ("100,000 nested lists, chunked", "POST", JOBS, typed, [b"[" * 100_000, b"]" * 100_000], 413),
        ("30,000 nested lists", "POST", JOBS, typed, b"[" * 30_000 + b"]" * 30_000, 400),
        ("30 nested lists", "POST", JOBS, typed, b"[" * 30 + b"]" * 30, 400),
        ("not JSON", "POST", JOBS, typed, b"{kind: dance}", 400),
        ("a JSON list", "POST", JOBS, typed, body([dance_job(song_id, model)]), 400),
        ("song id a number", "POST", JOBS, typed, body({**dance_job(song_id, model), "song": 5}), 400),
        ("song id a list", "POST", JOBS, typed, body({**dance_job(song_id, model), "song": [song_id]}), 400),
        ("song id null", "POST", JOBS, typed, body({**dance_job(song_id, model), "song": None}), 400),
        ("model id a number", "POST", JOBS, typed, body({**dance_job(song_id, model), "model": 7}), 400),
        ("model id a list", "POST", JOBS, typed, body({**dance_job(song_id, model), "model": [model]}), 400),
        ("pose model id a path", "POST", JOBS, typed,
         body({**dance_job(song_id, model), "pose_model": "../cache"}), 400),
        ("video id null", "POST", JOBS, typed, body({"kind": "preview", "video": None}), 400),
        ("video id a list", "POST", JOBS, typed, body({"kind": "train", "video": [1]}), 400),
        ("kind a number", "POST", JOBS, typed, body({"kind": 3}), 400),
        ("kind null", "POST", JOBS, typed, body({"kind": None}), 400),
        ("unknown kind", "POST", JOBS, typed, body({"kind": "shell", "command": "touch pwned"}), 400),
        ("unknown field", "POST", JOBS, typed, body({**dance_job(song_id, model), "command": "ls"}), 400),
        ("seed a list", "POST", JOBS, typed, body({**dance_job(song_id, model), "seed": [1]}), 400),
    ]


def forged_origins(work: Path, song: Path, model: str) -> Tally:
    tally = Tally("forged and malformed requests")
    data, port, errors = work / "web_forged", free_port(), []
    with running_server(work, data, port, errors):
        song_id = upload_song(port, song)
        uploads = set((data / "uploads").iterdir())
        slowest = (0.0, "")
        for what, method, path, headers, body, expected in forged_requests(port, song_id, model):
            jobs = len(api(port, "GET", JOBS)[1])
            started = time.monotonic()
            status, answer = request(port, method, path, headers, body)
            seconds = time.monotonic() - started
            slowest = max(slowest, (seconds, what))
            ok = (status == expected and isinstance(answer, dict) and set(answer) == {"error"}
                  and isinstance(answer["error"], str) and answer["error"].endswith(".") and seconds < 10.0
                  and len(api(port, "GET", JOBS)[1]) == jobs)
            if not ok:
                print(f"  {what}: {status} (expected {expected}) in {seconds:.1f} s: {str(answer)[:300]}", flush=True)
            tally.add(ok, [], [])
        alive = api(port, "GET", CONFIG)[0] == 200
    tally.note = f"slowest answer {slowest[0]:.2f} s ({slowest[1]})"
    tally.add(alive, errors, temporaries(data) + sorted(map(str, set((data / "uploads").iterdir()) - uploads)))
    return tally


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--kills", type=int, default=6, help="kill -9 trials (default 6)")
    parser.add_argument("--writers", type=int, default=3, help="two-writer trials (default 3)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--work", type=Path, help="work folder (default: a new temporary one, deleted after)")
    parser.add_argument("--no-server", action="store_true", help="skip the web server's cases")
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="fault_campaign_"))
    work.mkdir(parents=True, exist_ok=True)
    rng = random.Random(args.seed)
    start = time.time()
    try:
        data, run = work / "data", work / "pose_models" / POSE_RUN
        for setup in (["make-dataset", "--out", str(data), "--clips", "6", "--seconds", "10", "--workers", "1"],
                      ["train-pose", *LSTM, "--data", str(data), "--out", str(run), "--epochs", "1"]):
            done = cli(*setup, "-q")
            if done.returncode != 0:
                sys.exit(f"setup failed: {' '.join(setup[:1])}: {done.stderr}")
        song = sorted((data / "audio").iterdir())[0]
        model = None if args.no_server else tiny_appearance_model(work, data)
        print(f"setup done in {time.time() - start:.0f} s", flush=True)
        tallies = [two_writers(work, run, song, args.writers), kill_during_saves(work, data, song, args.kills, rng),
                   *full_and_read_only(work, data, run, song)]
        if model is not None:
            tallies += [broken_off("two servers, one --data", lambda: two_servers(work, song, model)),
                        broken_off("kill -9 of the server mid-job",
                                   lambda: kill_server_mid_job(work, song, model, args.kills, rng)),
                        broken_off("forged and malformed requests", lambda: forged_origins(work, song, model))]
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)
    print("\n| case | ran | passed | tracebacks | leftovers | note |\n|---|---|---|---|---|---|")
    for t in tallies:
        print(f"| {t.case} | {t.ran} | {t.passed} | {t.tracebacks} | {t.leftovers} | {t.note} |")
    print(f"\n{time.time() - start:.0f} s in all")
    sys.exit(0 if all(t.passed == t.ran for t in tallies) else 1)


if __name__ == "__main__":
    main()
