"""Jobs of the web app: one folder per job under ``DATA/jobs/``, run one at a time in a spawned worker process.

```
DATA/jobs/<id>/job.json     kind, title, params, state (queued -> running -> done | failed | cancelled |
                            interrupted), times, error sentence, outputs (name -> path relative to DATA), command,
                            warnings (sentences the tool logged as warnings)
DATA/jobs/<id>/log.txt      everything the worker logged, progress lines included
DATA/jobs/<id>/result.json  what the worker hands back: its outputs or an error sentence, and its warnings
DATA/jobs/<id>/out/         the job's own files (deleted when the job is cancelled or interrupted)
DATA/server.lock            held (flock) by the one server using the folder; holds its process id
```

Only the server process writes ``job.json`` (under one lock); the worker writes the other files. Appearance
models train into the cache, whose checkpoints are atomic, so a cancelled training leaves a resumable entry. A job
found running when the server starts lost its worker with the previous server: it becomes interrupted, which is
only true when no other server uses the folder, so a server takes :class:`DataFolderLock` before it touches it.
"""

from __future__ import annotations

import fcntl
import json
import multiprocessing
import os
import re
import shutil
import threading
import time
import uuid
from pathlib import Path

from apps.web.job_folder import JOB_FILE, LOG_FILE, OUT, RESULT_FILE, write_json
from apps.web.tasks import run_job
from dancesynth.core.errors import DancesynthError

JOBS = "jobs"
LOCK_FILE = "server.lock"
FINISHED = ("done", "failed", "cancelled", "interrupted")
# Seconds a cancelled worker gets (SIGTERM) to finish its training step, save the appearance model and delete
# its temporary files before it is killed: one step of the 256-px model takes up to ~10 s on a 2-core CPU.
TERMINATE_GRACE_S = 30.0
POLL_S = 0.2
LOG_TAIL_BYTES = 16384
JOB_ID = re.compile(r"^[0-9]{8}-[0-9]{6}-[0-9a-f]{6}$")
# dancesynth.core.progress's log line: "rendering: 120/480 frame (25%), 4.0 frame/s, 1m30s left"
PROGRESS_LINE = re.compile(r"^(?P<what>[\w -]+): (?P<done>\d+)/(?P<total>\d+) (?P<unit>\S+) \((?P<percent>\d+)%\)")


def parse_progress(text: str) -> dict | None:
    """The latest progress line of a log as ``{"what", "done", "total", "unit", "percent", "left", "took",
    "line"}`` (``left`` / ``took``: durations such as ``1m30s``, or None), or None when there is none."""
    for line in reversed(text.splitlines()):
        m = PROGRESS_LINE.match(line)
        if m:
            left, took = re.search(r", (\w+) left", line), re.search(r", took (\w+)", line)
            return {"what": m["what"], "done": int(m["done"]), "total": int(m["total"]), "unit": m["unit"],
                    "percent": int(m["percent"]), "left": left and left[1], "took": took and took[1],
                    "line": line}
    return None


def _tail(path: Path) -> str:
    if not path.is_file():
        return ""
    with open(path, "rb") as f:
        f.seek(max(0, path.stat().st_size - LOG_TAIL_BYTES))
        return f.read().decode("utf-8", "replace")


class DataFolderLock:
    """One server's exclusive hold on its data folder (``flock`` on ``DATA/server.lock``, released by
    :meth:`release` or when the process ends, however it ends). A second holder, in this process or another, is
    refused with a sentence naming the first one's process id."""

    def __init__(self, data: Path) -> None:
        data.mkdir(parents=True, exist_ok=True)
        self._file = open(data / LOCK_FILE, "a+")  # not "w": the holder's pid must stay readable to the refused
        try:
            fcntl.flock(self._file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._file.seek(0)
            holder = self._file.read().strip()
            self._file.close()
            raise DancesynthError(f"Another dancesynth server{f' (process {holder})' if holder.isdigit() else ''} "
                                  f"is using the data folder {data}; stop it first, or give this one another "
                                  "--data.") from None
        self._file.truncate(0)
        self._file.write(f"{os.getpid()}\n")
        self._file.flush()

    def release(self) -> None:
        self._file.close()


class JobStore:
    """The jobs under ``data/jobs`` and the thread that runs them, one at a time, each in a fresh spawned
    process (``settings`` go to every worker: the cache folder, the device and the data folder)."""

    def __init__(self, data: Path, settings: dict) -> None:
        self.data = Path(data)
        self.root = self.data / JOBS
        self.root.mkdir(parents=True, exist_ok=True)
        self.settings = settings
        self._lock = threading.RLock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._running: tuple[str, multiprocessing.Process] | None = None
        self._cancelled: dict[str, float] = {}  # job id -> when its worker was asked to stop
        self._thread: threading.Thread | None = None

    # --- state files -------------------------------------------------------------------------------------
    def folder(self, job_id: str) -> Path:
        """The job's folder; KeyError for an id that names no job."""
        if not JOB_ID.match(job_id) or not (self.root / job_id / JOB_FILE).is_file():
            raise KeyError(job_id)
        return self.root / job_id

    def _read(self, job_id: str) -> dict:
        return json.loads((self.folder(job_id) / JOB_FILE).read_text())

    def _write(self, job: dict) -> None:
        write_json(self.root / job["id"] / JOB_FILE, job)

    def _all(self) -> list[dict]:
        jobs = [json.loads(p.read_text()) for p in self.root.glob(f"*/{JOB_FILE}")]
        return sorted(jobs, key=lambda j: j["created"])

    def create(self, kind: str, title: str, params: dict, command: str | None = None) -> dict:
        """Queue a job; returns its view (see :meth:`view`)."""
        job_id = f"{time.strftime('%Y%m%d-%H%M%S')}-{uuid.uuid4().hex[:6]}"
        job = {"id": job_id, "kind": kind, "title": title, "params": params, "command": command,
               "state": "queued", "created": time.time(), "started": None, "finished": None, "error": None,
               "outputs": {}, "info": {}, "warnings": []}
        with self._lock:
            (self.root / job_id).mkdir()
            self._write(job)
        self._wake.set()
        return self.view(job)

    def view(self, job: dict, queued: list[str] | None = None) -> dict:
        """``job`` plus what the page shows: ``position`` in the queue (1 = next), the latest ``progress``
        line parsed (see :func:`parse_progress`) and the ``last_line`` of the log."""
        if queued is None:
            queued = [j["id"] for j in self._all() if j["state"] == "queued"]
        log = _tail(self.root / job["id"] / LOG_FILE)
        lines = [line for line in log.splitlines() if line.strip()]
        return {**job, "position": queued.index(job["id"]) + 1 if job["id"] in queued else None,
                "progress": parse_progress(log), "last_line": lines[-1] if lines else None}

    def jobs(self) -> list[dict]:
        """Every job, newest first."""
        jobs = self._all()
        queued = [j["id"] for j in jobs if j["state"] == "queued"]
        return [self.view(j, queued) for j in reversed(jobs)]

    def active(self) -> list[dict]:
        """The queued and running jobs."""
        return [j for j in self._all() if j["state"] in ("queued", "running")]

    def get(self, job_id: str) -> dict:
        return self.view(self._read(job_id))

    def output(self, job_id: str, name: str) -> Path:
        """The file of one of the job's outputs; KeyError when the job has no output of that name."""
        return self.data / self._read(job_id)["outputs"][name]

    def log(self, job_id: str) -> str:
        return _tail(self.folder(job_id) / LOG_FILE)

    # --- running -----------------------------------------------------------------------------------------
    def start(self) -> None:
        """Mark jobs the previous server left running as interrupted, then start running queued jobs."""
        for job in self._all():
            if job["state"] == "running":
                self._end(job, "interrupted", error="The server stopped while this job ran; start it again.")
        self._thread = threading.Thread(target=self._loop, name="dancesynth-jobs", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the worker of the running job (it becomes interrupted) and the thread."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join()
        if self._running is not None:
            job_id, process = self._running
            self._terminate(process)
            self._end(self._read(job_id), "interrupted", error="The server stopped while this job ran; "
                                                               "start it again.")
            self._running = None

    def cancel(self, job_id: str) -> dict:
        """Cancel a queued job at once, or stop a running job's worker (the thread then removes its outputs)."""
        with self._lock:
            job = self._read(job_id)
            if job["state"] == "queued":
                self._end(job, "cancelled")
            elif job["state"] == "running" and self._running is not None and self._running[0] == job_id:
                self._cancelled.setdefault(job_id, time.monotonic())
                self._running[1].terminate()
        self._wake.set()
        return self.get(job_id)

    def _end(self, job: dict, state: str, error: str | None = None, outputs: dict | None = None,
             info: dict | None = None, warnings: list[str] | None = None) -> None:
        with self._lock:
            if state in ("cancelled", "interrupted"):
                shutil.rmtree(self.root / job["id"] / OUT, ignore_errors=True)
            job.update(state=state, finished=time.time(), error=error, outputs=outputs or {},
                       info={**job.get("info", {}), **(info or {})}, warnings=warnings or [])
            self._write(job)

    def _loop(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                if self._running is not None:
                    self._check_running()
                if self._running is None:
                    queued = [j for j in self._all() if j["state"] == "queued"]
                    if queued:
                        self._launch(queued[0])
            self._wake.wait(POLL_S)
            self._wake.clear()

    def _launch(self, job: dict) -> None:
        process = multiprocessing.get_context("spawn").Process(
            target=run_job, args=(str(self.root / job["id"]), self.settings), name=f"dancesynth-job-{job['id']}")
        process.start()
        job.update(state="running", started=time.time(), pid=process.pid)
        self._write(job)
        self._running = (job["id"], process)

    def _check_running(self) -> None:
        job_id, process = self._running
        asked = self._cancelled.get(job_id)
        if process.is_alive():
            if asked is not None and time.monotonic() - asked > TERMINATE_GRACE_S:
                process.kill()
            return
        process.join()
        self._running = None
        job = self._read(job_id)
        result_file = self.root / job_id / RESULT_FILE
        result = json.loads(result_file.read_text()) if result_file.is_file() else None
        if self._cancelled.pop(job_id, None) is not None:
            self._end(job, "cancelled")
        elif result is not None and result.get("error") is None:
            self._end(job, "done", outputs=result.get("outputs"), info=result.get("info"),
                      warnings=result.get("warnings"))
        elif result is not None:
            self._end(job, "failed", error=result["error"], warnings=result.get("warnings"))
        else:
            self._end(job, "failed", error=f"The job's worker stopped unexpectedly (exit status "
                                           f"{process.exitcode}); its log has the details.")

    def _terminate(self, process: multiprocessing.Process) -> None:
        process.terminate()
        process.join(TERMINATE_GRACE_S)
        if process.is_alive():
            process.kill()
            process.join()
