"""The web app's answers to bad and oversized input: bodies bounded as they arrive (chunked ones too), uploads
stored under names the server chooses, every field's type checked, every error ``{"error": sentence}`` with a 4xx,
and damaged cache entries listed as such; sent to the ASGI app directly (no browser, no socket, no worker)."""

import json
import tempfile
from collections.abc import Iterable
from pathlib import Path

import pytest
import soundfile
from web_client import BOUNDARY, FORM, JSON, PAGE, call, form, wav

from apps.web.server import JOB_BYTES, JSON_DEPTH, create_app

MB = 2**20
# A whole training's metadata as the trainer leaves it in a cache entry (what /api/models reads of it).
LATEST = {"kind": "stage2", "epoch": 1, "total_epochs": 4, "trained_seconds": 30.0, "step": 20,
          "config": {"width": 64, "height": 64}, "validation": {"ssim": 0.5, "psnr": 20.0}}


def endless_upload(megabytes: int) -> Iterable[bytes]:
    """The start of an upload form, then ``megabytes`` MB of its file, 1 MB at a time (made as they are read)."""
    yield form("song", "huge.wav", b"")[: -len(f"\r\n--{BOUNDARY}--\r\n")]
    for _ in range(megabytes):
        yield bytes(MB)


@pytest.fixture
def app(tmp_path, monkeypatch):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))  # where a spooled upload would land
    app = create_app(tmp_path / "data", tmp_path / "cache", device="cpu", max_upload_mb=1.0)
    app.state.web.start_cleanup.join(60)
    yield app
    app.state.web.close()


def _leftovers(app) -> list[Path]:
    """Every file under the data folder's uploads and the temporary folder."""
    uploads = app.state.web.data / "uploads"
    return [p for root in (uploads, Path(tempfile.gettempdir())) if root.is_dir() for p in root.rglob("*")]


# --- bounded bodies ---------------------------------------------------------------------------------------------
def test_a_chunked_upload_over_the_limit_is_stopped_at_the_limit_and_leaves_nothing(app):
    status, answer, read = call(app, "POST", "/api/uploads", FORM, endless_upload(300))
    assert status == 413
    assert answer["error"] == ("huge.wav is larger than that, over this server's upload limit of 1 MB; use a shorter "
                               "file or start the server with a larger --max-upload-mb.")
    assert read <= 3 * MB  # of the 300 MB sent
    assert _leftovers(app) == []


def test_an_upload_declared_over_the_limit_is_refused_before_its_body_is_read(app):
    body = form("song", "song.wav", bytes(2 * MB))
    status, answer, read = call(app, "POST", "/api/uploads", {**FORM, "X-File-Name": "song.wav"}, body)
    assert status == 413 and answer["error"].startswith("song.wav is 2 MB, over this server's upload limit of 1 MB")
    assert read == 0 and _leftovers(app) == []


def test_a_big_job_request_is_refused_before_it_is_read_whole(app):
    status, answer, read = call(app, "POST", "/api/jobs", JSON, (b" " * MB for _ in range(300)))
    assert status == 413 and answer["error"].startswith("A job request is at most 64 KB of JSON")
    assert read <= JOB_BYTES + MB
    big = json.dumps({"kind": "demo", "minutes": 2, "pad": "x" * JOB_BYTES}).encode()
    status, answer, read = call(app, "POST", "/api/jobs", JSON, big)
    assert status == 413 and read == 0
    assert app.state.web.jobs.jobs() == []


@pytest.mark.parametrize("depth", [JSON_DEPTH + 1, 30_000, 100_000])
def test_deeply_nested_json_is_a_sentence_without_being_parsed(app, depth, monkeypatch):
    """(Its answer's time: ``benchmarks/fault_campaign.py``'s forged requests.)"""
    parsed, loads = [], json.loads

    def recording(text, **kwargs):
        parsed.append(text)
        return loads(text, **kwargs)

    monkeypatch.setattr(json, "loads", recording)
    status, answer, _ = call(app, "POST", "/api/jobs", JSON, b"[" * depth + b"]" * depth)
    assert not any(isinstance(text, str) and text.startswith("[" * (JSON_DEPTH + 1)) for text in parsed)
    if 2 * depth > JOB_BYTES:
        assert status == 413
    else:
        assert status == 400 and answer["error"] == (f"A job request nests more than {JSON_DEPTH} levels deep; it "
                                                     "is a flat JSON object, as the page sends.")


# --- names the server chooses -----------------------------------------------------------------------------------
@pytest.mark.parametrize("filename", ["upload.json", "../upload.json", "media.wav", "song.wav"])
def test_an_upload_is_stored_under_a_name_the_server_chooses(app, filename):
    status, meta, _ = call(app, "POST", "/api/uploads", FORM, form("song", filename, wav()))
    assert status == 200, meta
    folder = app.state.web.data / "uploads" / meta["id"]
    assert sorted(p.name for p in folder.iterdir()) == sorted(["upload.json", f"media.{filename.rsplit('.')[-1]}"])
    assert json.loads((folder / "upload.json").read_text()) == meta
    assert meta["name"] == Path(filename).name and meta["kind"] == "song" and meta["duration"] == pytest.approx(2.0)
    assert soundfile.info(str(folder / meta["file"])).duration == pytest.approx(2.0)
    # The song is usable: a dance job finds it (and names it by the user's name).
    status, job, _ = call(app, "POST", "/api/jobs", JSON, json.dumps({"kind": "dance", "song": meta["id"],
                                                                       "model": "0" * 24 + "-small"}).encode())
    assert status == 400 and "no appearance model" in job["error"]


def test_a_refused_upload_is_named_by_the_users_name_and_leaves_nothing(app):
    status, answer, _ = call(app, "POST", "/api/uploads", FORM, form("song", "my song.mp3", b"not a song" * 100))
    assert status == 400 and "my_song.mp3" in answer["error"] and "media" not in answer["error"]
    assert "uploads/" not in answer["error"] and _leftovers(app) == []


@pytest.mark.parametrize("body, says", [
    (form(None, "song.wav", b"RIFF"), "Unknown upload kind None; choose song or video."),
    (form("poem", "song.wav", b"RIFF"), "Unknown upload kind 'poem'; choose song or video."),
    (form("song", "song.wav", b""), "song.wav is empty (0 bytes); upload a complete file."),
    (f"--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"kind\"\r\n\r\nsong\r\n--{BOUNDARY}--\r\n".encode(),
     "The upload has no file"),
    (form("song", "a.wav", b"RIFF")[:-20], "The upload ended before its last byte"),
    (form("song", "a.wav", b"RIFF").replace(b'name="kind"', b'name="colour"'), "a field 'colour' it should not have"),
    (form("song" * 100, "a.wav", b"RIFF"), "The upload form's field 'kind' is longer than 64 bytes"),
])
def test_a_malformed_upload_form_is_a_sentence(app, body, says):
    status, answer, _ = call(app, "POST", "/api/uploads", FORM, body)
    assert status == 400 and says in answer["error"]
    assert _leftovers(app) == []


def test_an_upload_that_is_no_form_is_a_sentence(app):
    status, answer, _ = call(app, "POST", "/api/uploads", {**PAGE, "Content-Type": "application/json"}, b"{}")
    assert status == 400 and answer["error"].startswith("An upload is a multipart form (the fields kind and file)")


# --- every field's type -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("body, says", [
    ({"kind": 5}, "The job kind of a job request must be a name"),
    ({"kind": ["dance"]}, "The job kind of a job request must be a name"),
    ({"kind": None}, "Unknown job kind None"),
    ({"kind": "dance", "song": 5}, "The song of a job request must be a name"),
    ({"kind": "dance", "song": ["a"]}, "The song of a job request must be a name"),
    ({"kind": "dance", "song": None}, "Choose a song"),
    ({"kind": "dance", "song": {"id": "x"}}, "The song of a job request must be a name"),
    ({"kind": "dance", "song": "a" * 12, "pose_model": 3}, "The pose model of a job request must be a name"),
    ({"kind": "dance", "song": "a" * 12, "model": [1]}, "The appearance model of a job request must be a name"),
    ({"kind": "dance", "song": "a" * 12, "video": None}, "No uploaded song 'aaaaaaaaaaaa'"),
    ({"kind": "train", "video": 7}, "The video of a job request must be a name"),
    ({"kind": "train", "video": "b" * 12, "preset": ["small"]}, "The preset of a job request must be a name"),
    ({"kind": "preview", "video": None}, "No uploaded video ''"),
    ({"kind": "preview", "video": 12}, "The video of a job request must be a name"),
    ({"kind": "demo", "minutes": "1_0"}, "The demo's time budget (minutes) must be a number, got '1_0'."),
    ({"kind": "demo", "minutes": "0x10"}, "must be a number, got '0x10'"),
    ({"kind": "demo", "minutes": "nan"}, "must be a number, got 'nan'"),
    ({"kind": "demo", "minutes": True}, "must be a number, got True"),
    ({"kind": "demo", "minutes": [2]}, "must be a number, got [2]"),
    ({"kind": "demo", "minutes": {"m": 2}}, "must be a number, got {'m': 2}"),
    ({"kind": "demo", "minutes": 1e308}, "must be between 1.01 and 1440"),
])
def test_a_job_request_with_a_field_of_the_wrong_type_is_a_sentence(app, body, says):
    status, answer, _ = call(app, "POST", "/api/jobs", JSON, json.dumps(body).encode())
    assert status == 400 and says in answer["error"], answer
    assert app.state.web.jobs.jobs() == []


@pytest.mark.parametrize("body, field", [
    ({"kind": "demo", "minutes": 2, "seed": 3}, "'seed'"),
    ({"kind": "preview", "video": "a" * 12, "minutes": 2}, "'minutes'"),
    ({"kind": "train", "video": "a" * 12, "command": "touch pwned"}, "'command'"),
    ({"kind": "dance", "song": "builtin:x", "out": "/etc/passwd"}, "'out'"),
])
def test_a_job_request_with_a_field_its_kind_has_not_is_refused(app, body, field):
    status, answer, _ = call(app, "POST", "/api/jobs", JSON, json.dumps(body).encode())
    fields = {"demo": "kind, minutes", "preview": "kind, video", "train": "kind, model, video, minutes, preset",
              "dance": "kind, song, start, duration, seed, pose_model, model, video, minutes, preset"}[body["kind"]]
    assert status == 400 and answer == {"error": f"Unknown field {field} in a {body['kind']} job request; send only "
                                                 f"its fields ({fields}), as the page does."}
    assert app.state.web.jobs.jobs() == []


def test_numbers_come_as_json_numbers_or_as_the_pages_decimal_text(app):
    for minutes in (2, 2.5, "2", " 2.5 ", "3e0"):
        status, job, _ = call(app, "POST", "/api/jobs", JSON, json.dumps({"kind": "demo", "minutes": minutes}).encode())
        assert status == 200 and job["params"]["minutes"] == float(minutes)


@pytest.mark.parametrize("method, path, headers, status, says", [
    ("GET", "/api/jobs/x/files/dance.mp4?download=maybe", PAGE, 400, "The request's query download is wrong"),
    ("GET", "/api/nothing", PAGE, 404, "There is no /api/nothing on this server; reload the page."),
    ("DELETE", "/api/jobs", PAGE, 405, "This server does not answer DELETE /api/jobs; reload the page."),
    ("GET", "/api/jobs/20250101-000000-abcdef", PAGE, 404, "There is no '20250101-000000-abcdef' here"),
])
def test_every_error_is_a_sentence(app, method, path, headers, status, says):
    answer_status, answer, _ = call(app, method, path, headers)
    assert answer_status == status and set(answer) == {"error"} and answer["error"].startswith(says)


# --- damaged cache entries --------------------------------------------------------------------------------------
def _entry(cache: Path, name: str, source: object = None, losses: str | None = None) -> Path:
    """A cache entry as a training leaves it: latest.json, its source.json (``source``: its contents) and
    losses.csv."""
    folder = cache / f"{name * 24}-small"
    folder.mkdir(parents=True)
    (folder / "latest.json").write_text(json.dumps(LATEST))
    (folder / "source.json").write_text(json.dumps(source if source is not None else
                                                   {"video": f"/videos/{name}.mp4", "preset": "small"}))
    (folder / "losses.csv").write_text(losses or "step,epoch,seconds,loss_g,loss_d\n1,0,1.0,2.5,0.5\n2,0,2.0,nan,0.4\n")
    return folder


@pytest.mark.parametrize("damage, says", [
    ({"source": {"video": 5}}, "source.json holds {'video': 5}, not the path of a video"),
    ({"source": ["a", "list"]}, "source.json holds a JSON list, not an object; it was edited or damaged, so delete "
                                "the folder"),
    ({"losses": "step,loss_g\n1,2.5\n2,abc\n"}, "losses.csv is damaged"),
    ({"losses": "step,loss_g\n1,2.5,7\n"}, "losses.csv is damaged"),
])
def test_a_damaged_cache_entry_is_listed_as_damaged_beside_the_others(app, damage, says):
    cache = app.state.web.cache
    good, bad = _entry(cache, "a"), _entry(cache, "b", **damage)
    status, models, _ = call(app, "GET", "/api/models", PAGE)
    assert status == 200
    listed = {m["name"]: m for m in models}
    assert listed[good.name]["damaged"] is None and listed[good.name]["video"] == "a.mp4"
    assert listed[good.name]["ssim"] == 0.5 and listed[good.name]["size"] == [64, 64]
    assert says in listed[bad.name]["damaged"] and listed[bad.name]["video"] is None
    # The good one's curves (a diverged step is null, not NaN); the damaged one is refused by a sentence.
    status, losses, _ = call(app, "GET", f"/api/models/{good.name}/losses", PAGE)
    assert status == 200 and losses == {"step": [1, 2], "series": {"loss_g": [2.5, None], "loss_d": [0.5, 0.4]}}
    status, answer, _ = call(app, "POST", "/api/jobs", JSON, json.dumps({"kind": "train", "model": bad.name}).encode())
    assert status == 400 and says in answer["error"]
    if "losses" in damage:
        status, answer, _ = call(app, "GET", f"/api/models/{bad.name}/losses", PAGE)
        assert status == 400 and says in answer["error"]


def test_a_model_is_listed_with_the_scores_of_the_checkpoint_it_renders_with(app):
    cache = app.state.web.cache
    kept = _entry(cache, "k")
    best = {"step": 12, "ssim": 0.7, "psnr": 24.0, "select_ssim": 0.8}
    (kept / "latest.json").write_text(json.dumps({**LATEST, "best": best}))
    status, models, _ = call(app, "GET", "/api/models", PAGE)
    listed = next(m for m in models if m["name"] == kept.name)
    assert status == 200 and (listed["step"], listed["ssim"], listed["psnr"]) == (12, 0.7, 24.0)


def test_a_damaged_latest_json_is_listed_as_damaged(app):
    cache = app.state.web.cache
    _entry(cache, "a")
    bad = _entry(cache, "c")
    (bad / "latest.json").write_text(json.dumps({**LATEST, "validation": {"ssim": "high"}}))
    other = _entry(cache, "d")
    (other / "latest.json").write_text("{not json")
    status, models, _ = call(app, "GET", "/api/models", PAGE)
    damaged = {m["name"]: m["damaged"] for m in models}
    assert status == 200 and len(models) == 3 and damaged.pop("a" * 24 + "-small") is None
    assert "its ssim is 'high', not a number" in damaged[bad.name]
    assert "is not dancesynth checkpoint metadata" in damaged[other.name]
