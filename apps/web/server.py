"""The web app's HTTP side: the page (``static/``) and a JSON API over uploads, built-in songs, cached
appearance models and jobs (:mod:`apps.web.jobs`).

```
GET  /                              the page            GET  /api/config          limits, preset menu
POST /api/uploads (file, kind)      a song or a video   GET  /api/songs           built-in songs (made on first use)
GET  /api/models                    cached appearance models, with held-out SSIM and training time
GET  /api/pose-models               the built-in pose model and the stage-1 runs of --pose-models
GET  /api/models/{name}/losses      the model's loss curves (losses.csv)   .../sample: its latest sample image
POST /api/jobs {kind, ...}          queue a dance, train, preview or demo job
GET  /api/jobs, /api/jobs/{id}      state, queue position, progress     POST /api/jobs/{id}/cancel
GET  /api/jobs/{id}/files/{name}    an output (?download=1: as an attachment)
```

Uploads older than ``keep_uploads_hours`` are removed at start and at each new upload, unless a queued or
running job uses them or a cached model names them as its video (continuing its training needs it).

Every error answers ``{"error": sentence}``: bad input status 400 (413 for an upload over the size limit or a job
request over :data:`JOB_BYTES`), with the :class:`~dancesynth.core.errors.DancesynthError` sentence the CLI would
print; every field of a job request is checked for its type first, and a field its kind has not
(:data:`JOB_FIELDS`) is refused rather than ignored. Bodies are bounded while they arrive: an upload
is written into its folder as it streams and stopped at the limit (:mod:`apps.web.uploads`), a job request is
read up to :data:`JOB_BYTES` and its JSON nesting checked before it is parsed. A cached model that cannot be read
is listed with the sentence saying why (``damaged``), beside the others.

One server uses a data folder at a time (:class:`~apps.web.jobs.DataFolderLock`, taken before anything in it is
touched); :func:`serve` also takes its port before, so a second server, a port in use or an address that is not
this machine's is one sentence and changes nothing.

The server answers its own page only: a request whose ``Host`` is not the address it listens on (``localhost``,
``127.0.0.1`` and ``[::1]`` too when that is the loopback) with its port gets 403, which stops DNS rebinding; a
request that changes something (any method but GET, HEAD and OPTIONS) must name the page as its ``Origin`` (or,
without one, its ``Referer``), else 403, which stops other sites' forms and scripts; a job request must be
``application/json``, else 415 (a cross-site form cannot send that type).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import errno
import functools
import ipaddress
import json
import logging
import math
import re
import shlex
import shutil
import socket
import threading
import time
import uuid
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import urlsplit

from fastapi import APIRouter, FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException

from apps.requests import MINUTES_A_DAY, DanceRequest, DemoRequest, ExtractPosesRequest, Page, TrainVideoRequest, shown
from apps.web.jobs import DataFolderLock, JobStore
from apps.web.uploads import (
    FORM_BYTES,
    UPLOAD_META,
    UPLOADS,
    UploadForm,
    display_name,
    receive_form,
    too_big,
    user_message,
)
from dancesynth.core.errors import DancesynthError
from stage2_video.presets import AUTO, AUTO_MEANS, PRESETS, preset_names, resolve_preset

if TYPE_CHECKING:
    from apps.demo import DemoPlan

logger = logging.getLogger(__name__)

STATIC = Path(__file__).parent / "static"
SONGS = "songs"
# Built-in songs: a few, short enough to be made in seconds on first use.
BUILTIN_SONGS, BUILTIN_SECONDS = 3, 30.0
SONG_CHECK_RATE = 8000  # Hz: enough to check that a file holds audible sound, and fast
BUILTIN_POSE_MODEL = "built-in (Dance Revolution)"  # stage1_pose.pretrained.DEFAULT_POSE_MODEL
NO_CACHE = {"Cache-Control": "no-store"}
# A job request is a flat object of a few short fields; these bound what is read and parsed before it is checked.
JOB_BYTES = 64 * 1024
JSON_DEPTH = 8
# The text fields of job requests (ids, names), by the words a sentence uses for them, and their longest length.
TEXT_FIELDS = {"kind": "job kind", "song": "song", "video": "video", "model": "appearance model",
               "pose_model": "pose model", "preset": "preset"}
TEXT_CHARS = 200
# The fields of each kind of job request: what the page sends (static/app.js), and a dance's preset besides.
JOB_FIELDS = {"dance": ("kind", "song", "start", "duration", "seed", "pose_model", "model", "video", "minutes",
                        "preset"),
              "train": ("kind", "model", "video", "minutes", "preset"),
              "preview": ("kind", "video"),
              "demo": ("kind", "minutes")}
# A training job's minutes are minutes more (train-video's --minutes counts the run's time in all), 10 when not sent.
TRAIN_MORE = Page("minutes", "training budget (minutes)", 0.05, MINUTES_A_DAY)
TRAIN_MORE_DEFAULT = 10.0
LOSSES = "losses.csv"
LOSS_ROWS = 500  # the page's loss plot needs no more
# What GET /api/models tells of each cached model.
MODEL_FIELDS = ("name", "preset", "video", "video_path", "trained_seconds", "finished", "ssim", "psnr", "step", "size",
                "damaged")
# The JSON API's routes sit under this prefix; uploads are refused by size before their body is read.
API = "/api"
CONFIG_ROUTE, UPLOADS_ROUTE, JOBS_ROUTE = "/config", "/uploads", "/jobs"
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
# Requests of these methods only read; every other method needs the page's own Origin.
SAFE_METHODS = ("GET", "HEAD", "OPTIONS")
DEFAULT_PORTS = {"http": 80, "https": 443}


class BodyTooLarge(DancesynthError):
    """A request body over its size limit (HTTP 413 rather than 400)."""

    status = 413


class NotJson(DancesynthError):
    """A request body that should be JSON sent as another media type (HTTP 415 rather than 400)."""

    status = 415


def _address(text: str) -> str:
    """An address or host name as compared: lower case, without IPv6 brackets, IPv4-mapped IPv6 as IPv4."""
    text = text.strip("[]").lower()
    with contextlib.suppress(ValueError):
        ip = ipaddress.ip_address(text)
        return str(getattr(ip, "ipv4_mapped", None) or ip)
    return text


def _is_loopback(address: str) -> bool:
    with contextlib.suppress(ValueError):
        return ipaddress.ip_address(address).is_loopback
    return address == "localhost"


def _url_address(scheme: str, netloc: str) -> tuple[str, int] | None:
    """(host, port) of ``netloc`` (``host[:port]``; the scheme's port when none is given), None when it is
    anything else (a user name, a path)."""
    try:
        parts = urlsplit(f"{scheme}://{netloc}")
        port = parts.port or DEFAULT_PORTS.get(scheme)
    except ValueError:
        return None
    if "@" in netloc or parts.netloc != netloc or not parts.hostname or not port:
        return None
    return _address(parts.hostname), port


def _page_address(url: str, scheme: str) -> tuple[str, int] | None:
    """(host, port) of the page ``url`` (an Origin or a Referer), None when it is not a ``scheme`` URL."""
    try:
        parts = urlsplit(url)
    except ValueError:
        return None
    return _url_address(scheme, parts.netloc) if parts.scheme == scheme else None


def foreign_request(request: Request, bound: str | None) -> str | None:
    """Why ``request`` does not come from this server's own page (a sentence for a 403), or None when it does.

    The server's address is the one the connection arrived at (and ``bound``, the name the server was started
    with); ``Host`` must name it, or a loopback name when it is the loopback, with the server's port. Unless the
    method only reads, ``Origin`` (or without one ``Referer``) must be a URL on such an address too.
    """
    address, port = request.scope.get("server") or (None, None)
    names = {_address(name) for name in (address, bound) if name and name not in ("0.0.0.0", "::")}
    if any(_is_loopback(name) for name in names):
        names |= set(LOOPBACK_NAMES)
    own = {(name, port) for name in names}
    scheme = request.url.scheme
    host = request.headers.get("host", "")
    if _url_address(scheme, host) not in own:
        page = f"[{address}]:{port}" if ":" in str(address) else f"{address}:{port}"
        named = f"not for {host!r}" if host else "and this request names none"
        return f"This server answers requests for {page} only, {named}; open the page at {scheme}://{page}/."
    if request.method in SAFE_METHODS:
        return None
    origin = request.headers.get("origin") or request.headers.get("referer") or ""
    if _page_address(origin, scheme) not in own:
        source = f"comes from {origin!r}" if origin else "names no page"
        return (f"Only this server's own page may change something here, and this request {source}; use the page "
                f"at {scheme}://{host}/.")
    return None


@contextlib.contextmanager
def _no_error_paths(data: Path):
    """Turn a DancesynthError raised inside into one whose sentence names uploads by their own file name."""
    try:
        yield
    except DancesynthError as e:
        raise DancesynthError(user_message(str(e), data)) from e


def offered_presets() -> list[dict]:
    """The appearance-model presets the page's menu offers, ``auto`` first: ``{"name", "label"}`` each."""
    return [{"name": name, "label": f"{name} ({AUTO_MEANS if name == AUTO else PRESETS[name]})"}
            for name in preset_names(auto=True)]


def _check_types(body: dict) -> None:
    """Refuse a job request whose text fields (:data:`TEXT_FIELDS`) hold anything but text (or null) of at most
    :data:`TEXT_CHARS` characters; its numbers are checked as they are read
    (:meth:`apps.requests.Request.from_form`)."""
    for key, what in TEXT_FIELDS.items():
        value = body.get(key)
        if value is not None and (not isinstance(value, str) or len(value) > TEXT_CHARS):
            raise DancesynthError(f"The {what} of a job request must be a name of at most {TEXT_CHARS} characters, "
                                  f"got {shown(value)}; reload the page and try again.")


def _json_depth(text: str) -> int:
    """How deep the arrays and objects of the JSON ``text`` nest (brackets inside strings not counted)."""
    depth = deepest = 0
    for bracket in re.findall(r"[\[\]{}]", re.sub(r'"(?:[^"\\]|\\.)*"', "", text)):
        depth += 1 if bracket in "[{" else -1
        deepest = max(deepest, depth)
    return deepest


async def read_job_request(request: Request) -> dict:
    """The JSON object of a job request, read up to :data:`JOB_BYTES` (413 past it, its declared length refused
    before any of it is read) and checked to nest at most :data:`JSON_DEPTH` deep before it is parsed."""
    media_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media_type != "application/json":
        raise NotJson(f"A job request is JSON, not {media_type or 'untyped'!r}; send it with Content-Type: "
                      "application/json, as the page does.")
    too_long = BodyTooLarge(f"A job request is at most {JOB_BYTES // 1024} KB of JSON; send only the fields of "
                            "the job, as the page does.")
    length = request.headers.get("content-length", "")
    if length.isdigit() and int(length) > JOB_BYTES:
        raise too_long
    raw = bytearray()
    async for chunk in request.stream():
        raw += chunk
        if len(raw) > JOB_BYTES:
            raise too_long
    try:
        text = raw.decode("utf-8")
        if _json_depth(text) > JSON_DEPTH:
            raise DancesynthError(f"A job request nests more than {JSON_DEPTH} levels deep; it is a flat JSON "
                                  "object, as the page sends.")
        body = json.loads(text)
    except ValueError:
        body = None
    if not isinstance(body, dict):
        raise DancesynthError("A job request is a JSON object; reload the page and try again.")
    return body


def _finite(value: object, what: str) -> float | None:
    """``value`` when it is a finite number, None when it is None or not finite (JSON has no NaN); a ValueError
    naming ``what`` when it is anything else."""
    if value is None:
        return None
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise ValueError(f"its {what} is {shown(value)}, not a number")
    return value if math.isfinite(value) else None


def _read_losses(path: Path) -> dict:
    """The loss columns of a ``losses.csv``: ``{"step": [...], "series": {name: [...]}}``, at most
    :data:`LOSS_ROWS` evenly spread rows, a value that is not finite (a diverged step) None; a
    :class:`DancesynthError` when one of those rows holds something else than numbers."""
    if not path.is_file():
        return {"step": [], "series": {}}
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    rows = rows[:: max(1, len(rows) // LOSS_ROWS)]
    keys = [k for k in (rows[0] if rows else {}) if k not in ("step", "epoch", "lr", "seconds")]
    try:
        return {"step": [int(r["step"]) for r in rows],
                "series": {k: [_finite(float(r[k]), k) for r in rows] for k in keys}}
    except (KeyError, TypeError, ValueError) as e:
        raise DancesynthError(f"{path} is damaged (a row of it holds {type(e).__name__}: {e}); delete the appearance "
                              f"model's folder {path.parent} and train it again.") from e


def _source_video(entry: Path) -> str | None:
    """The video a cache entry's ``source.json`` names, None when it has none; an error (ValueError, OSError)
    when the file cannot be read or names something else than a path."""
    from stage2_video.model_cache import SOURCE_FILE

    source = entry / SOURCE_FILE
    if not source.is_file():
        return None
    meta = json.loads(source.read_text())
    if not isinstance(meta, dict) or not isinstance(meta.get("video", ""), str):
        raise ValueError(f"{SOURCE_FILE} holds {shown(meta)}, not the path of a video")
    return meta.get("video")


class WebApp:
    """What the routes share: the data folder (held, see :class:`~apps.web.jobs.DataFolderLock`, until
    :meth:`close`), the cache, the limits and the job store."""

    def __init__(self, data: Path, cache: Path | None, device: str, max_upload_mb: float,
                 max_song_minutes: float, pose_models: Path | None = None, keep_uploads_hours: float = 24.0,
                 demo: DemoPlan | None = None) -> None:
        self.data = Path(data).resolve()
        self._cache = Path(cache).resolve() if cache is not None else None
        self.pose_models_dir = Path(pose_models).resolve() if pose_models is not None else None
        if self.pose_models_dir is not None and not self.pose_models_dir.is_dir():
            raise DancesynthError(f"The pose models folder {pose_models} does not exist; give --pose-models the "
                                  "folder holding your `dancesynth train-pose` runs.")
        self.device = device
        self.max_upload_mb = max_upload_mb
        self.max_song_minutes = max_song_minutes
        self.keep_uploads_hours = keep_uploads_hours
        self.demo = demo
        self.lock = DataFolderLock(self.data)
        try:
            # A worker resolves the default cache itself; the demo's sizes go as a dict (None: DemoPlan()).
            self.jobs = JobStore(self.data, {"data": str(self.data), "cache": self._cache and str(self._cache),
                                             "device": device, "demo": demo and dataclasses.asdict(demo)})
        except BaseException:
            self.lock.release()
            raise
        self._songs_lock = threading.Lock()
        self._uploads_lock = threading.Lock()  # a cleanup never removes an upload a job is being made from
        # The start's cleanup runs aside: its cache lookup imports torch, which would hold the page back seconds.
        self.start_cleanup = threading.Thread(target=self.clean_uploads, name="dancesynth-clean-uploads", daemon=True)

    @functools.cached_property
    def cache(self) -> Path:
        """The appearance-model cache (its default is looked up on first use: that import loads torch)."""
        from stage2_video.model_cache import default_cache_dir

        return self._cache or default_cache_dir()

    def close(self) -> None:
        """Stop the jobs (a running one becomes interrupted) and let the data folder go."""
        self.jobs.stop()
        self.lock.release()

    # --- uploads -----------------------------------------------------------------------------------------
    async def receive_upload(self, request: Request) -> dict:
        """Store the upload ``request`` sends (see :mod:`apps.web.uploads`) under ``DATA/uploads/<id>/`` after
        checking it is a song or a video of a person's length; an upload refused on the way or by the check leaves
        nothing behind."""
        folder = self.data / UPLOADS / uuid.uuid4().hex[:12]
        folder.mkdir(parents=True)
        try:
            form = await receive_form(request, folder, self.max_upload_mb)
            meta = await run_in_threadpool(self._check_upload, form)
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        await run_in_threadpool(self.clean_uploads)
        return meta

    def _check_upload(self, form: UploadForm) -> dict:
        """Check the received upload is what its ``kind`` says and write its ``upload.json``; its metadata."""
        kind, name = form.fields.get("kind"), display_name(form.filename)
        if kind not in ("song", "video"):
            raise DancesynthError(f"Unknown upload kind {shown(kind)}; choose song or video.")
        if form.size == 0:
            raise DancesynthError(f"{name} is empty (0 bytes); upload a complete file.")
        try:
            duration = self._check_song(form.path, name) if kind == "song" else self._check_video(form.path)
        except DancesynthError as e:
            raise DancesynthError(user_message(str(e).replace(str(form.path), name), self.data)) from e
        meta = {"id": form.path.parent.name, "kind": kind, "name": name, "file": form.path.name,
                "duration": duration, "size": form.size}
        (form.path.parent / UPLOAD_META).write_text(json.dumps(meta))
        return meta

    def clean_uploads(self) -> list[str]:
        """Remove the upload folders older than ``keep_uploads_hours`` (by their ``upload.json``) that no queued or
        running job uses and no cache entry's ``source.json`` names as its video; returns the removed ids."""
        root = self.data / UPLOADS
        if not root.is_dir():
            return []
        oldest = time.time() - 3600 * self.keep_uploads_hours
        with self._uploads_lock:
            used = {str(v) for job in self.jobs.active() for v in job["params"].values()}
            for entry in self.cache.glob("*/"):
                with contextlib.suppress(OSError, ValueError):  # a damaged entry protects no upload
                    used.add(_source_video(entry) or "")
            removed = []
            for folder in root.iterdir():
                meta = folder / UPLOAD_META
                # A folder without upload.json is an upload being saved, or one a killed server left.
                with contextlib.suppress(FileNotFoundError):
                    if (meta if meta.is_file() else folder).stat().st_mtime >= oldest:
                        continue
                    if not any(path.startswith(f"{folder}/") for path in used):
                        shutil.rmtree(folder, ignore_errors=True)
                        removed.append(folder.name)
        if removed:
            logger.info(f"removed {len(removed)} upload(s) older than {self.keep_uploads_hours:g} h")
        return removed

    def _check_song(self, path: Path, name: str) -> float:
        from dancesynth.core.media import load_song

        seconds = len(load_song(path, SONG_CHECK_RATE)) / SONG_CHECK_RATE
        if seconds > 60 * self.max_song_minutes:
            raise DancesynthError(f"{name} lasts {seconds / 60:.1f} min, over this server's limit of "
                                  f"{self.max_song_minutes:g} min; cut the part you want to dance to, or start the "
                                  "server with a larger --max-song-minutes.")
        return seconds

    def _check_video(self, path: Path) -> float:
        from dancesynth.core.media import probe_video
        from stage2_video.model_cache import check_target_video

        check_target_video(path)
        return probe_video(path).duration

    def upload(self, upload_id: str, kind: str) -> dict:
        """The metadata of an upload of ``kind`` and its file's ``path``."""
        meta_file = self.data / UPLOADS / upload_id / UPLOAD_META
        if not re.fullmatch(r"[0-9a-f]{12}", upload_id) or not meta_file.is_file():
            raise DancesynthError(f"No uploaded {kind} {upload_id!r} on this server; upload it again.")
        meta = json.loads(meta_file.read_text())
        if meta["kind"] != kind:
            raise DancesynthError(f"{meta['name']} was uploaded as a {meta['kind']}, not a {kind}; upload it again.")
        # Uploads stored before the server chose their names are under their own name.
        return {**meta, "path": str(meta_file.parent / meta.get("file", meta["name"]))}

    # --- built-in songs and cached models ----------------------------------------------------------------
    def songs(self) -> list[dict]:
        """The built-in songs, made into ``DATA/songs`` on first use."""
        from stage1_pose.data.make_dataset import make_dataset
        from stage1_pose.pretrained import TRAINING_DATA_SEED

        root = self.data / SONGS
        with self._songs_lock:
            if not (root / "manifest.json").is_file():
                shutil.rmtree(root, ignore_errors=True)  # what an interrupted first use left
                # Songs the shipped pose model never heard.
                make_dataset(root, clips=BUILTIN_SONGS, seconds=BUILTIN_SECONDS, seed=TRAINING_DATA_SEED + 1,
                             workers=1, progress=False)
        songs = []
        for clip in json.loads((root / "manifest.json").read_text())["clips"]:
            tempo = json.loads((root / clip["beats"]).read_text()).get("tempo")
            songs.append({"id": f"builtin:{clip['id']}", "name": f"{clip['style']} ({tempo:.0f} BPM, "
                          f"{BUILTIN_SECONDS:g} s)", "path": str(root / clip["audio"]), "duration": BUILTIN_SECONDS})
        return songs

    def song(self, song_id: str) -> dict:
        if song_id.startswith("builtin:"):
            for song in self.songs():
                if song["id"] == song_id:
                    return song
            raise DancesynthError(f"There is no built-in song {song_id!r}; pick one from the list.")
        if not song_id:
            raise DancesynthError("Choose a song: upload one or pick a built-in one.")
        return self.upload(song_id, "song")

    def model_path(self, name: str) -> Path:
        from dancesynth.core.checkpoint import has_checkpoint

        path = self.cache / str(name)
        if not re.fullmatch(r"[0-9a-f]{24}-\w+", str(name)) or not path.is_dir():
            raise DancesynthError(f"There is no appearance model {name!r} in the cache {self.cache}; pick one "
                                  "from the list.")
        if not has_checkpoint(path) and not (path / LOSSES).is_file():
            raise DancesynthError(f"The appearance model {name} has not trained yet; train it first.")
        return path

    def models(self) -> list[dict]:
        """The trained entries of the cache, newest first. One that cannot be read is listed too, by its ``name``
        and ``damaged``: the sentence saying why (its other fields None), so it hides none of the others."""
        from dancesynth.core.checkpoint import POINTER

        found = []
        for folder in [p for p in self.cache.iterdir() if p.is_dir()] if self.cache.is_dir() else []:
            try:
                model = self._model(folder)
            except DancesynthError as e:
                model = {**dict.fromkeys(MODEL_FIELDS), "name": folder.name, "damaged": str(e)}
            except (OSError, KeyError, TypeError, ValueError, AttributeError) as e:
                reason = f"{type(e).__name__}: {e}".rstrip(".")
                model = {**dict.fromkeys(MODEL_FIELDS), "name": folder.name,
                         "damaged": f"The appearance model {folder.name} in the cache is damaged ({reason}); "
                                    f"delete its folder {folder} and train it again."}
            if model is not None:
                found.append(model)

        def newest_first(model: dict) -> float:
            with contextlib.suppress(OSError):
                return -(self.cache / model["name"] / POINTER).stat().st_mtime
            return 0.0

        return sorted(found, key=newest_first)

    def _model(self, folder: Path) -> dict | None:
        """What :meth:`models` lists of one cache entry, None when it has not trained yet; the reading's error
        when a file of it is damaged. Numbers that are not finite (a diverged training's SSIM) are None."""
        from dancesynth.core.checkpoint import load_meta
        from stage2_video.model_cache import read_entry
        from stage2_video.training_data import rendered_checkpoint

        entry = read_entry(folder)
        if entry is None:
            return None
        meta = load_meta(folder, "stage2")
        _read_losses(folder / LOSSES)
        video = _source_video(folder) or meta.get("video") or ""
        rendered, config = rendered_checkpoint(meta), meta["config"]
        numbers = {key: _finite(value, key) for key, value in (
            ("ssim", rendered.get("ssim")), ("psnr", rendered.get("psnr")), ("step", rendered.get("step")),
            ("width", config.get("width")), ("height", config.get("height")))}
        if not math.isfinite(entry.trained_seconds):
            raise ValueError(f"its trained_seconds is {entry.trained_seconds}")
        return {"name": folder.name, "preset": entry.preset, "video": Path(user_message(video, self.data)).name,
                "video_path": video,
                "trained_seconds": entry.trained_seconds, "finished": entry.finished, "ssim": numbers["ssim"],
                "psnr": numbers["psnr"], "step": numbers["step"], "size": [numbers["width"], numbers["height"]],
                "damaged": None}

    def model(self, name: str) -> dict:
        """The listing of the appearance model ``name`` (see :meth:`models`), refused when it is damaged."""
        path = self.model_path(name)
        model = next((m for m in self.models() if m["name"] == path.name), None)
        if model is None:
            raise DancesynthError(f"The appearance model {name} has not trained yet; train it first.")
        if model["damaged"]:
            raise DancesynthError(model["damaged"])
        return model

    def pose_models(self) -> list[dict]:
        """The built-in pose model (id "") and every stage-1 run in the --pose-models folder or one level down
        (id: its path relative to that folder), each named by folder and method."""
        from dancesynth.core.checkpoint import load_meta

        found = [{"id": "", "name": BUILTIN_POSE_MODEL}]
        root = self.pose_models_dir
        if root is None or not root.is_dir():
            return found
        for run in sorted({p.parent for pattern in ("*/latest.json", "*/*/latest.json") for p in root.glob(pattern)}):
            try:
                method = load_meta(run, "stage1")["method"]
            except (DancesynthError, KeyError):
                continue  # another kind of run (an appearance model) or a broken one: not offered
            run_id = run.relative_to(root).as_posix()
            found.append({"id": run_id, "name": f"{run_id} ({method})"})
        return found

    def pose_model_path(self, run_id: str) -> Path:
        """The run folder of a pose model from :meth:`pose_models`, checked to still be a stage-1 run."""
        from dancesynth.core.checkpoint import load_meta

        root = self.pose_models_dir
        path = (root / str(run_id)).resolve() if root is not None else None
        if path is None or not path.is_relative_to(root) or path == root or not path.is_dir():
            raise DancesynthError(f"There is no pose model {run_id!r} on this server; reload the page and pick "
                                  "one from the list.")
        load_meta(path, "stage1")
        return path

    def losses(self, name: str) -> dict:
        """The loss curves of the model (see :func:`_read_losses`)."""
        return _read_losses(self.model_path(name) / LOSSES)

    def sample(self, name: str) -> Path:
        samples = sorted((self.model_path(name) / "samples").glob("step_*.png"))
        if not samples:
            raise DancesynthError(f"The appearance model {name} has no sample image yet.")
        return samples[-1]

    # --- jobs --------------------------------------------------------------------------------------------
    def _demo_command(self, request: DemoRequest) -> str:
        """The command running what a demo job runs: `dancesynth demo`, or with a plan other than the default
        (which `dancesynth demo` has no options for) the Python call the job makes."""
        if self.demo is None or self.demo == type(self.demo)():  # not DemoPlan(): apps.demo imports torch
            return shlex.join(request.to_command())
        arguments = "".join(f"{name}={value!r}, " for name, value in request.api_kwargs().items())
        return shlex.join(["python", "-c", f"from apps.demo import DemoPlan, run_demo; "
                                           f"run_demo({arguments}plan={self.demo!r})"])

    def create_job(self, body: dict) -> dict:
        """Check a job request (one sentence for what is wrong) and queue it."""
        _check_types(body)
        kind = body.get("kind")
        fields = JOB_FIELDS.get(kind, ())
        unknown = next((key for key in body if fields and key not in fields), None)
        if unknown is not None:
            raise DancesynthError(f"Unknown field {shown(unknown)} in a {kind} job request; send only its fields "
                                  f"({', '.join(fields)}), as the page does.")
        with _no_error_paths(self.data), self._uploads_lock:
            if kind == "dance":
                return self._dance_job(body)
            if kind in ("train", "preview"):
                return self._train_job(body) if kind == "train" else self._preview_job(body)
            if kind == "demo":
                request = DemoRequest.from_form(body, out=str(self.data / "demo"), device=self.device)
                return self.jobs.create("demo", f"demo, {request.minutes:g} min", dataclasses.asdict(request),
                                        self._demo_command(request))
        raise DancesynthError(f"Unknown job kind {shown(kind)}; choose dance, train, preview or demo.")

    def _dance_job(self, body: dict) -> dict:
        pose = self.pose_model_path(body["pose_model"]) if body.get("pose_model") else None
        song = self.song(body.get("song") or "")
        if body.get("model"):
            model = self.model(body["model"])
            # The training budget goes with a video only; a model's job ignores it, as the page does not send it.
            person = {"video_model": str(self.cache / model["name"]), "train_minutes": None}
            target = f"{model['video']} ({model['preset']})"
        else:
            if not body.get("video"):
                raise DancesynthError("Choose the person: a trained appearance model or an uploaded video.")
            video = self.upload(body["video"], "video")
            person = {"target": video["path"], "preset": resolve_preset(body.get("preset", AUTO), self.device),
                      "cache": str(self.cache)}
            target = video["name"]
        # The job's outputs are named relative to its folder (tasks.dance_job puts them there).
        request = DanceRequest.from_form(body, song=song["path"], pose_model=pose and str(pose), out="dance.mp4",
                                         skeleton_preview="skeleton.mp4", side_by_side="side_by_side.mp4",
                                         device=self.device, **person)
        if request.start > song["duration"] - 1.0:
            raise DancesynthError(f"The segment start {request.start:g} s is too close to the end of the song, which "
                                  f"lasts {song['duration']:.1f} s; choose a start at least 1 s before its end.")
        return self.jobs.create("dance", f"{song['name']} danced by {target}", dataclasses.asdict(request),
                                shlex.join(request.to_command()))

    def _train_job(self, body: dict) -> dict:
        from stage2_video.model_cache import entry_path, read_entry

        if body.get("model"):
            model = self.model(body["model"])
            video = Path(model["video_path"])
            if not video.is_file():
                raise DancesynthError(f"The video the model {model['name']} was trained on is gone; upload it again "
                                      "to continue its training.")
            preset, name = model["preset"], video.name
        else:
            if not body.get("video"):
                raise DancesynthError("Upload a video of the person, or pick a model to continue.")
            upload = self.upload(body["video"], "video")
            video, name = Path(upload["path"]), upload["name"]
            preset = resolve_preset(body.get("preset", AUTO), self.device)
        entry = entry_path(video, preset, self.cache)
        more = TRAIN_MORE.read(body, TRAIN_MORE_DEFAULT, integer=False)
        trained = read_entry(entry)
        done = trained.trained_seconds / 60 if trained is not None else 0.0
        request = TrainVideoRequest(video=str(video), out=str(entry), preset=preset, minutes=more + done,
                                    resume=trained is not None, device=self.device)
        return self.jobs.create("train", f"appearance model of {name}, {more:g} min more",
                                {"target": str(video), "minutes": more, "preset": preset, "entry": entry.name},
                                shlex.join(request.to_command()))

    def _preview_job(self, body: dict) -> dict:
        upload = self.upload(body.get("video") or "", "video")
        request = ExtractPosesRequest(video=upload["path"], out="poses.npz", preview="preview.mp4")
        return self.jobs.create("preview", f"who is tracked in {upload['name']}", {"target": upload["path"]},
                                shlex.join(request.to_command()))


def create_app(data: Path, cache: Path | None = None, device: str = "auto", max_upload_mb: float = 500.0,
               max_song_minutes: float = 10.0, pose_models: Path | None = None, keep_uploads_hours: float = 24.0,
               demo: DemoPlan | None = None, host: str | None = None) -> FastAPI:
    """The web app over the data folder ``data`` (uploads, built-in songs, jobs and their outputs), the
    appearance-model cache ``cache`` (default: the one `dance --target` uses) and the folder of stage-1 runs
    ``pose_models`` offered besides the built-in pose model. Uploads are kept ``keep_uploads_hours`` (see
    :meth:`WebApp.clean_uploads`); the Demo tab runs ``demo`` (default ``DemoPlan()``). ``host``: the name or
    address the server is started on, accepted in requests' Host besides the address they arrive at (see
    :func:`foreign_request`). The data folder is held from here until the app's lifespan ends (or
    ``app.state.web.close()``); a :class:`DancesynthError` when another server holds it."""
    web = WebApp(data, cache, device, max_upload_mb, max_song_minutes, pose_models, keep_uploads_hours, demo)
    web.start_cleanup.start()

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI):
        web.jobs.start()
        yield
        web.close()

    app = FastAPI(title="dancesynth", lifespan=lifespan, docs_url=None, redoc_url=None, openapi_url=None)
    app.state.web = web
    app.mount("/static", StaticFiles(directory=STATIC), name="static")

    @app.exception_handler(DancesynthError)
    async def bad_input(request: Request, e: DancesynthError) -> JSONResponse:
        return JSONResponse({"error": str(e)}, status_code=getattr(e, "status", 400))

    @app.exception_handler(KeyError)
    async def not_found(request: Request, e: KeyError) -> JSONResponse:
        return JSONResponse({"error": f"There is no {e.args[0]!r} here; reload the page."}, status_code=404)

    @app.exception_handler(RequestValidationError)
    async def bad_request(request: Request, e: RequestValidationError) -> JSONResponse:
        problem = next(iter(e.errors()), {})
        where = " ".join(str(part) for part in problem.get("loc", ()))
        what = str(problem.get("msg", "is not what this server reads")).rstrip(".")
        return JSONResponse({"error": f"The request's {where or 'content'} is wrong ({what}); reload the page and "
                                      "try again."}, status_code=400)

    @app.exception_handler(HTTPException)
    async def http_error(request: Request, e: HTTPException) -> JSONResponse:
        what = f"{request.method} {request.url.path}"
        error = {404: f"There is no {request.url.path} on this server; reload the page.",
                 405: f"This server does not answer {what}; reload the page."}.get(
            e.status_code, f"This server cannot answer {what} ({e.status_code}: {e.detail}); reload the page.")
        return JSONResponse({"error": error}, status_code=e.status_code, headers=e.headers)

    @app.exception_handler(Exception)
    async def server_error(request: Request, e: Exception) -> JSONResponse:
        # The server's console has the traceback (uvicorn logs the exception after this answer).
        return JSONResponse({"error": f"The server failed on this request ({type(e).__name__}: {shown(str(e))}); "
                                      "its console has the details."}, status_code=500)

    @app.middleware("http")
    async def checks(request: Request, call_next):
        refusal = foreign_request(request, host)
        if refusal is not None:
            return JSONResponse({"error": refusal}, status_code=403)
        # Refuse an oversized upload from its declared length, before its body is read.
        length = request.headers.get("content-length", "")
        limit = web.max_upload_mb * 2**20 + FORM_BYTES  # the form's own fields come on top of the file
        if request.url.path == API + UPLOADS_ROUTE and length.isdigit() and int(length) > limit:
            error = too_big(request.headers.get("x-file-name"), int(length), web.max_upload_mb)
            return JSONResponse({"error": str(error)}, status_code=413)
        return await call_next(request)

    api = APIRouter(prefix=API)

    @app.get("/")
    def index() -> FileResponse:
        return FileResponse(STATIC / "index.html", headers=NO_CACHE)

    @api.get(CONFIG_ROUTE)
    def config() -> dict:
        return {"max_upload_mb": web.max_upload_mb, "max_song_minutes": web.max_song_minutes,
                "cache": str(web.cache), "data": str(web.data), "device": web.device, "presets": offered_presets()}

    @api.post(UPLOADS_ROUTE)
    async def upload(request: Request) -> dict:
        return await web.receive_upload(request)

    @api.get("/songs")
    def songs() -> list[dict]:
        return [{k: s[k] for k in ("id", "name", "duration")} for s in web.songs()]

    @api.get("/models")
    def models() -> list[dict]:
        return web.models()

    @api.get("/pose-models")
    def pose_models() -> list[dict]:
        return web.pose_models()

    @api.get("/models/{name}/losses")
    def losses(name: str) -> dict:
        return web.losses(name)

    @api.get("/models/{name}/sample")
    def sample(name: str) -> FileResponse:
        return FileResponse(web.sample(name), headers=NO_CACHE)

    @api.post(JOBS_ROUTE)
    async def create_job(request: Request) -> dict:
        return await run_in_threadpool(web.create_job, await read_job_request(request))

    @api.get(JOBS_ROUTE)
    def jobs() -> list[dict]:
        return web.jobs.jobs()

    @api.get(JOBS_ROUTE + "/{job_id}")
    def job(job_id: str) -> dict:
        return web.jobs.get(job_id)

    @api.get(JOBS_ROUTE + "/{job_id}/log")
    def job_log(job_id: str) -> dict:
        return {"log": web.jobs.log(job_id)}

    @api.post(JOBS_ROUTE + "/{job_id}/cancel")
    def cancel(job_id: str) -> dict:
        return web.jobs.cancel(job_id)

    @api.get(JOBS_ROUTE + "/{job_id}/files/{name:path}")
    def job_file(job_id: str, name: str, download: bool = False) -> FileResponse:
        path = web.jobs.output(job_id, name)
        if not path.is_file():
            raise DancesynthError(f"The output {name} of this job is gone from the server's data folder.")
        return FileResponse(path, filename=path.name if download else None,
                            content_disposition_type="attachment" if download else "inline")

    app.include_router(api)
    return app


def listen(host: str, port: int) -> socket.socket:
    """A socket listening on ``host`` (an address of this machine or its name; IPv6 when it holds a colon) at
    ``port``; a :class:`DancesynthError` saying why there is none: a port in use, reserved or out of range, or a
    host that is not this machine's."""
    try:
        return _bound(host, port)
    except OverflowError as e:
        raise DancesynthError(f"The port {port} does not exist; choose one from 1024 to 65535 with --port.") from e
    except socket.gaierror as e:
        raise DancesynthError(f"The host {host!r} is not an address or a known name ({e.strerror}); give --host an "
                              "address of this machine, e.g. 127.0.0.1 (this machine only) or 0.0.0.0 (its "
                              "networks).") from e
    except OSError as e:
        if e.errno == errno.EADDRINUSE:
            why = (f"port {port} on {host} is already in use (by another `dancesynth serve` or another program); "
                   "stop that, or choose another --port")
        elif e.errno == errno.EADDRNOTAVAIL:
            why = (f"{host} is not an address of this machine; give --host one of its addresses, e.g. 127.0.0.1 "
                   "(this machine only) or 0.0.0.0 (its networks)")
        elif e.errno in (errno.EACCES, errno.EPERM):
            why = f"port {port} is reserved for the system; choose one from 1024 to 65535 with --port"
        else:
            why = f"{e.strerror or e}; check --host and --port"
        raise DancesynthError(f"The server cannot listen on {host}:{port}: {why}.") from e


def _bound(host: str, port: int) -> socket.socket:
    """A socket bound to ``host``:``port`` and listening (IPv6 when ``host`` holds a colon)."""
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn: a restart need not wait TIME_WAIT
        sock.bind((host, port))
        sock.listen(2048)
        return sock
    except BaseException:
        sock.close()
        raise


def serve(host: str, port: int, data: Path, cache: Path | None = None, device: str = "auto",
          max_upload_mb: float = 500.0, max_song_minutes: float = 10.0, pose_models: Path | None = None,
          keep_uploads_hours: float = 24.0) -> None:
    """Run the web app until Ctrl-C. Its port and its data folder are taken first, so that a port in use, a bad
    host or a data folder another server uses is one sentence before anything changes."""
    import uvicorn

    sock = listen(host, port)
    try:
        app = create_app(data, cache, device, max_upload_mb, max_song_minutes, pose_models, keep_uploads_hours,
                         host=host)
    except BaseException:
        sock.close()
        raise
    logger.info(f"dancesynth web app on http://{host}:{port} (data in {app.state.web.data}; Ctrl-C stops it)")
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning"))
    server.run(sockets=[sock])
    if not server.started:
        raise DancesynthError("The web app did not start (the lines above say why); fix that and start it again.")
