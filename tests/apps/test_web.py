"""`dancesynth serve`: the web page in a real headless browser (Debian's chromium, driven by Playwright).

The server runs in a thread on a free port with a temporary data folder, a cache holding one tiny appearance
model and a folder of pose models holding one tiny stage-1 run.
Set DANCESYNTH_SCREENSHOTS=docs/screenshots to keep the screenshots of the tabs there (see README).
"""

import json
import os
import re
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile
import torch

torch.set_num_threads(1)

import uvicorn  # noqa: E402
from playwright.sync_api import Locator, Page, expect, sync_playwright  # noqa: E402

from apps.demo import DemoPlan  # noqa: E402
from apps.web.server import create_app  # noqa: E402
from dancesynth.core.media import probe_streams, probe_video, write_video  # noqa: E402
from dancesynth.core.skeleton import PoseSequence  # noqa: E402
from stage1_pose.train import train  # noqa: E402
from stage2_video.model_cache import SOURCE_FILE, entry_path  # noqa: E402
from stage2_video.presets import preset_names  # noqa: E402
from stage2_video.synthetic_person import appearance_preset, write_person_video  # noqa: E402
from stage2_video.train import TrainOptions, train_video  # noqa: E402
from stage2_video.training_data import video_digest  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
TINY_LSTM = dict(hidden=16, layers=1, dropout=0.0, window_frames=30, batch_size=4, epoch_windows=0)
TINY_VIDEO = {"width": 32, "height": 32, "ngf": 8, "n_downsample": 2, "n_blocks": 1, "ndf": 8, "batch_size": 4}
MAX_UPLOAD_MB, MAX_SONG_MINUTES = 2.0, 0.75
POSE_RUN = "mine/lstm"
JOB_TIMEOUT_MS = 180_000
REAL_CLIP = Path(__file__).parents[1] / "data" / "real_person" / "sports2d_demo_640x360.mp4"
# tests/apps/test_demo.py's toy demo, its training cut to min_train_minutes: the dance step keeps the rest.
TOY_DEMO = DemoPlan(clips=6, clip_seconds=12.0, target_seconds=4.0, target_size=128, dance_seconds=3.0,
                    finish_minutes=1.2, min_train_minutes=0.1, preset="small")


def _song(path: Path, seconds: float, sr: int = 8000) -> Path:
    """A chord with a click every half second (wav)."""
    t = np.arange(int(seconds * sr)) / sr
    soundfile.write(path, 0.2 * np.sin(2 * np.pi * 220 * t) + 0.5 * (np.mod(t, 0.5) < 0.02), sr)
    return path


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def server(tiny_stage1_dataset, tmp_path_factory):
    """(url, root folder, the tiny model's cache entry) of a running server."""
    root = tmp_path_factory.mktemp("web")
    # A 3-s synthetic person, and a model of them trained for a moment straight into the cache's entry folder.
    seq = PoseSequence.load(tiny_stage1_dataset / "poses" / "clip0.npz").slice_frames(0, 45)
    s = 64 / seq.height
    seq = PoseSequence(seq.keypoints * (s, s, 1), seq.fps, round(seq.width * s), 64)
    seq.save(root / "person.npz")
    video = root / "person.mp4"
    write_person_video(seq, video, appearance_preset("red_tee"))
    entry = entry_path(video, "small", root / "cache")
    train_video(video, entry, "small", TrainOptions(epochs=1, max_steps=2, val_frames=4), poses=root / "person.npz",
                device="cpu", overrides=TINY_VIDEO)
    (entry / SOURCE_FILE).write_text(json.dumps({"video_sha256": video_digest(video), "video": str(video),
                                                 "preset": "small"}))
    train("lstm", tiny_stage1_dataset, root / "pose_models" / POSE_RUN, overrides=TINY_LSTM, epochs=1, device="cpu")
    app = create_app(root / "data", root / "cache", device="cpu", max_upload_mb=MAX_UPLOAD_MB,
                     max_song_minutes=MAX_SONG_MINUTES, pose_models=root / "pose_models", demo=TOY_DEMO)
    port = _free_port()
    uv = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=uv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not uv.started and time.monotonic() < deadline:
        time.sleep(0.05)
    assert uv.started, "the server did not start"
    yield f"http://127.0.0.1:{port}", root, entry
    uv.should_exit = True
    thread.join(30)


@pytest.fixture(scope="module")
def browser():
    if not Path(CHROMIUM).is_file():
        pytest.fail(f"{CHROMIUM} is missing: the browser tests need Debian's chromium; run `make install` "
                    "(apt-get install -y chromium).", pytrace=False)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        yield browser
        browser.close()


@pytest.fixture
def page(browser, server):
    context = browser.new_context(accept_downloads=True, viewport={"width": 1200, "height": 900})
    page = context.new_page()
    page.goto(server[0])
    expect(page.locator("body[data-ready='1']")).to_be_attached()
    yield page
    context.close()


@pytest.fixture(scope="module")
def shots(tmp_path_factory) -> Path:
    folder = os.environ.get("DANCESYNTH_SCREENSHOTS")
    path = Path(folder) if folder else tmp_path_factory.mktemp("screenshots")
    path.mkdir(parents=True, exist_ok=True)
    return path


def _screenshot(page: Page, root: Path, path: Path) -> None:
    """Save a screenshot with the test's temporary folders shown as the server's default ones."""
    shown = [[str(root / "data"), "~/.local/share/dancesynth/web"],
             [str(root / "cache"), "~/.cache/dancesynth/appearance"], [str(root / "pose_models"), "runs/pose"]]
    page.evaluate("""pairs => { const w = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
      while (w.nextNode()) for (const [a, b] of pairs) w.currentNode.data = w.currentNode.data.replaceAll(a, b);
    }""", shown)
    page.screenshot(path=path, full_page=True)


def _upload(page: Page, selector: str, path: Path, status: str) -> None:
    page.set_input_files(selector, str(path))
    expect(page.locator(status)).to_contain_text("✓")


def _start_dance(page: Page, song: Path, model: str, duration: str = "", pose_model: str = "") -> str:
    """Upload ``song``, pick ``model`` and ``pose_model`` ("" = the built-in one), press Dance; returns the new
    job's id."""
    before = page.locator(".job[data-kind=dance]").count()
    _upload(page, "#song-file", song, "#song-status")
    page.select_option("#dance-model", model)
    page.select_option("#pose-model", pose_model)
    page.fill("#duration", duration)
    page.click("#dance-button")
    expect(page.locator(".job[data-kind=dance]")).to_have_count(before + 1)
    return page.locator(".job[data-kind=dance]").first.get_attribute("data-job")


def _press(page: Page, button: str, kind: str) -> Locator:
    """Press ``button`` and return the card of the ``kind`` job it queued."""
    before = page.locator(f".job[data-kind={kind}]").count()
    page.click(button)
    expect(page.locator(f".job[data-kind={kind}]")).to_have_count(before + 1)
    job = page.locator(f".job[data-kind={kind}]").first.get_attribute("data-job")
    return page.locator(f".job[data-job='{job}']")


def _wait_done(card: Locator, root: Path) -> None:
    """Wait for the job of ``card`` to be done; a failed job's log tells why."""
    try:
        expect(card).to_have_class(re.compile(r"\bdone\b"), timeout=JOB_TIMEOUT_MS)
    except AssertionError as e:
        log = root / "data" / "jobs" / card.get_attribute("data-job") / "log.txt"
        raise AssertionError(f"{e}\n{log.read_text() if log.is_file() else 'no log'}") from None


def test_dance_from_an_uploaded_song_to_a_downloaded_video(server, page, shots, tmp_path):
    _, root, entry = server
    song = _song(tmp_path / "my song.wav", 3.0)
    expect(page.locator("#pose-model option")).to_have_text(["built-in (Dance Revolution)", f"{POSE_RUN} (lstm)"])
    job = _start_dance(page, song, entry.name, duration="2", pose_model=POSE_RUN)
    card = page.locator(f".job[data-job='{job}']")
    expect(card).to_have_class(re.compile(r"\bdone\b"), timeout=JOB_TIMEOUT_MS)
    expect(card.locator(".progress-text")).to_contain_text("finished in")
    # Every video plays in the page.
    for name in ("dance", "side_by_side", "skeleton"):
        handle = card.locator(f"video[data-output={name}]").element_handle()
        page.wait_for_function("v => v.readyState >= 2 && v.duration > 0", arg=handle, timeout=30_000)
    assert "dancesynth dance" in card.locator("code.command").text_content()
    assert f"--video-model {entry}" in card.locator("code.command").text_content()
    assert f"--pose-model {root / 'pose_models' / POSE_RUN}" in card.locator("code.command").text_content()
    with page.expect_download() as download:
        card.locator("a.download").click()
    path = tmp_path / "downloaded.mp4"
    download.value.save_as(path)
    streams = probe_streams(path)
    assert streams["video_codec"] == "h264" and streams["video_frames"] > 0
    assert streams["audio_codec"] == "aac" and abs(streams["audio_duration"] - 2.0) < 0.2
    _screenshot(page, root, shots / "dance.png")


def test_a_song_and_a_video_of_a_person_give_a_downloaded_dance_and_a_cached_model(server, page, tmp_path):
    """The issue's done-when: from a song and a video of a person to a downloaded dance, no terminal."""
    _, root, _ = server
    _upload(page, "#song-file", _song(tmp_path / "song.wav", 3.0), "#song-status")
    _upload(page, "#dance-video", REAL_CLIP, "#dance-video-status")
    assert page.is_checked("input[name=target-source][value=video]")
    page.fill("#dance-minutes", "0")  # no training: the person's own pixels moved onto the dance
    page.fill("#duration", "2")
    card = _press(page, "#dance-button", "dance")
    _wait_done(card, root)
    assert "--target" in card.locator("code.command").text_content()
    with page.expect_download() as download:
        card.locator("a.download").click()
    path = tmp_path / "downloaded.mp4"
    download.value.save_as(path)
    streams, info = probe_streams(path), probe_video(path)
    assert streams["video_codec"] == "h264" and (info.width, info.height) == (640, 360)
    assert streams["audio_codec"] == "aac" and abs(streams["audio_duration"] - 2.0) < 0.2
    page.click("nav button[data-tab=models]")
    expect(page.locator("#models-table td", has_text=REAL_CLIP.name)).to_have_count(1)


def test_bad_input_gets_its_sentence_and_breaks_nothing(server, page, tmp_path):
    url, root, entry = server
    notes = tmp_path / "notes.txt"
    notes.write_text("not a song")
    page.set_input_files("#song-file", str(notes))
    status = page.locator("#song-status")
    expect(status).to_contain_text("notes.txt is not a readable audio or video file")
    assert str(root) not in status.text_content(), "the message names the user's file, not the server's folders"
    page.set_input_files("#song-file", str(_song(tmp_path / "long.wav", 50.0)))
    expect(status).to_contain_text("long.wav lasts 0.8 min, over this server's limit of 0.75 min")
    big = tmp_path / "big.mp3"
    big.write_bytes(b"\0" * int((MAX_UPLOAD_MB + 1) * 2**20))
    page.set_input_files("#song-file", str(big))
    expect(status).to_contain_text("over this server's upload limit of 2 MB")
    # The server refuses it too when a client skips the page's check (a client that is not a browser names the
    # page as its origin itself).
    answer = page.request.post(f"{url}/api/uploads", headers={"Origin": url}, multipart={
        "kind": "song", "file": {"name": "big.mp3", "mimeType": "audio/mpeg", "buffer": big.read_bytes()}})
    assert answer.status == 413 and "upload limit" in answer.json()["error"]
    page.set_input_files("#dance-video", str(notes))
    expect(page.locator("#dance-video-status")).to_contain_text("notes.txt is not a readable audio or video file")
    # Nothing was kept of the refused files, and the page still dances.
    assert not list((root / "data" / "uploads").glob("*/*.txt"))
    page.click("#dance-button")
    expect(page.locator("#dance-error")).to_contain_text("Choose a song file first")
    # A pose run that vanished since the page listed it, or that is not a pose model, gets its sentence.
    for run, says in (("mine/gone", "There is no pose model 'mine/gone' on this server"),
                      ("../cache", "There is no pose model '../cache' on this server")):
        answer = page.request.post(f"{url}/api/jobs", headers={"Origin": url}, data={"kind": "dance",
                                                                                   "pose_model": run})
        assert answer.status == 400 and answer.json()["error"].startswith(says)


def test_a_video_without_a_person_fails_its_preview_with_the_sentence(page, tmp_path):
    rng = np.random.default_rng(0)
    noise = tmp_path / "empty room.mp4"
    write_video(noise, [rng.integers(0, 255, (48, 64, 3), np.uint8) for _ in range(45)], 15.0)
    page.click("nav button[data-tab=models]")
    _upload(page, "#train-video", noise, "#train-video-status")
    page.click("#preview-button")
    card = page.locator(".job[data-kind=preview]").first
    expect(card).to_have_class(re.compile(r"\bfailed\b"), timeout=JOB_TIMEOUT_MS)
    expect(card.locator(".error")).to_contain_text("No person was found")
    expect(card.locator(".error")).to_contain_text("empty_room.mp4")


def test_continue_training_shows_the_live_plot_and_the_models_ssim(server, page, shots):
    _, root, entry = server
    page.click("nav button[data-tab=models]")
    row = page.locator(f"tr[data-model='{entry.name}']")
    assert re.fullmatch(r"0\.\d{3}", row.locator("td.ssim").text_content())
    page.fill("#train-minutes", "0.05")
    row.locator("button").click()
    card = page.locator(".job[data-kind=train]").first
    expect(card).to_have_class(re.compile(r"\bdone\b"), timeout=JOB_TIMEOUT_MS)
    expect(card.locator("svg.plot polyline").first).to_be_attached(timeout=10_000)
    expect(card.locator(".live img")).to_be_visible(timeout=10_000)
    assert "train-video" in card.locator("code.command").text_content()
    _screenshot(page, root, shots / "models.png")


def test_jobs_queue_survive_a_reload_show_progress_and_cancel(server, page, browser, tmp_path, shots):
    url, root, entry = server
    first = _start_dance(page, _song(tmp_path / "long song.wav", 40.0), entry.name)
    second = _start_dance(page, _song(tmp_path / "short.wav", 3.0), entry.name, duration="2")
    expect(page.locator(f".job[data-job='{second}'] .progress-text")).to_contain_text("waiting: next in the queue")
    expect(page.locator(f".job[data-job='{first}']")).to_have_class(re.compile(r"\brunning\b"),
                                                                    timeout=JOB_TIMEOUT_MS)
    page.reload()
    card = page.locator(f".job[data-job='{first}']")
    expect(card.locator(".progress-text")).to_have_text(re.compile(r"rendering: \d+/\d+ frame \(\d+%\), \w+ left"),
                                                        timeout=JOB_TIMEOUT_MS)
    _screenshot(page, root, shots / "progress.png")
    # A second browser sees the same jobs and cancels the running one; the queued one then runs.
    other = browser.new_context().new_page()
    other.goto(url)
    other.locator(f".job[data-job='{first}'] button.cancel").click()
    expect(card).to_have_class(re.compile(r"\bcancelled\b"), timeout=30_000)
    assert not (root / "data" / "jobs" / first / "out").exists(), "a cancelled job's outputs are removed"
    expect(other.locator(f".job[data-job='{second}']")).to_have_class(re.compile(r"\bdone\b"),
                                                                     timeout=JOB_TIMEOUT_MS)
    other.context.close()


def test_the_size_menu_offers_every_preset_and_auto(page):
    page.click("nav button[data-tab=models]")
    options = page.locator("#train-preset option")
    assert options.evaluate_all("os => os.map(o => o.value)") == list(preset_names(auto=True))
    expect(options.first).to_have_text(re.compile(r"^auto \(medium on GPUs"))


def test_demo_tab_checks_its_budget(page):
    page.click("nav button[data-tab=demo]")
    before = page.locator(".job[data-kind=demo]").count()
    page.fill("#demo-minutes", "0.5")
    page.click("#demo-button")
    expect(page.locator("#demo-error")).to_contain_text("must be between 1.01 and 1440")
    expect(page.locator(".job[data-kind=demo]")).to_have_count(before)


def test_demo_tab_runs_the_demo_and_shows_its_dance_and_summary(server, page, shots):
    _, root, _ = server
    page.click("nav button[data-tab=demo]")
    page.fill("#demo-minutes", "1.2")
    card = _press(page, "#demo-button", "demo")
    _wait_done(card, root)
    summary = card.locator(".markdown")
    expect(summary).to_contain_text("beat hit rate")
    expect(summary).to_contain_text("SSIM")
    expect(summary.locator("table").first).to_contain_text("real dance")
    handle = card.locator("video[data-output='dance.mp4']").element_handle()
    page.wait_for_function("v => v.readyState >= 2 && v.duration > 0", arg=handle, timeout=30_000)
    assert card.locator("a.download").get_attribute("href").endswith("dance.mp4?download=1")
    _screenshot(page, root, shots / "demo.png")


def test_a_jobs_warnings_show_on_its_card(server, page):
    """What the tool logs as a warning while a job runs (a target video that hides the person's hips) is handed
    back with the job (tests/apps/test_web_jobs.py) and shown on its card, also after the job ended."""
    _, root, entry = server
    folder = root / "data" / "jobs" / "19700101-000000-warned"
    folder.mkdir()
    sentence = "The target video shows the person's hips in fewer than half of its frames."
    (folder / "job.json").write_text(json.dumps({
        "id": folder.name, "kind": "train", "title": "a training", "params": {"entry": entry.name}, "command": None,
        "state": "done", "created": 0.0, "started": 1.0, "finished": 2.0, "error": None, "outputs": {}, "info": {},
        "warnings": [sentence]}))
    page.reload()
    card = page.locator(f".job[data-job='{folder.name}']")
    expect(card.locator(".warnings li")).to_have_text([sentence])
