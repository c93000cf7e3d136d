"""`dancesynth dance --target VIDEO`: one command from a real clip of a person to their dance, with the
appearance model cached by the video's content, reused, and continued when more minutes are asked for."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import soundfile
import torch

torch.set_num_threads(1)

import stage2_video.vgg  # noqa: E402
from apps.cli import main  # noqa: E402
from dancesynth.core.media import probe_streams, probe_video, read_frames, write_video  # noqa: E402
from stage2_video.composite import load_plate  # noqa: E402
from stage2_video.model_cache import entry_path  # noqa: E402

REAL_CLIP = Path(__file__).parents[1] / "data" / "real_person" / "sports2d_demo_640x360.mp4"
SR = 22050


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("dance_target")
    # Renamed: the cache is keyed by the video's content, not its name.
    clip = shutil.copy(REAL_CLIP, root / "me.mp4")
    t = np.arange(3 * SR) / SR
    soundfile.write(root / "song.wav", (0.2 * np.sin(2 * np.pi * 220 * t) + 0.5 * (np.mod(t, 0.5) < 0.02)), SR)
    return root, Path(clip), root / "song.wav", root / "cache"


def _dance(song: Path, clip: Path, cache: Path, out: Path, minutes: str) -> int:
    return main(["dance", str(song), "--target", str(clip), "--cache", str(cache), "--train-minutes", minutes,
                 "--preset", "small", "--duration", "2", "--out", str(out), "--device", "cpu"])


def _meta(entry: Path) -> dict:
    return json.loads((entry / "latest.json").read_text())


def test_target_renders_untrained_then_trains_once_then_reuses_then_continues(setup, capsys, monkeypatch):
    """One cache through every state a user meets, in one test: each call on the real clip costs tens of seconds,
    most of it finding the person in every frame, which the shared cache does once (separate tests would each
    redo it, in whichever test process runs them)."""
    root, clip, song, cache = setup
    entry = entry_path(clip, "small", cache)

    # 0 minutes: the person's own pixels, warped, at once; no word of a training loss, since nothing trains, nor of
    # hidden body parts: the clip shows him whole.
    monkeypatch.setattr(stage2_video.vgg, "_notice_shown", False)
    assert _dance(song, clip, cache, root / "zero.mp4", "0") == 0
    err = capsys.readouterr().err
    assert "perceptual loss" not in err and "shows the person's" not in err
    info = probe_video(root / "zero.mp4")
    assert (info.width, info.height) == (640, 360) and info.num_frames == 60
    assert _meta(entry)["step"] == 0 and (entry / "masks_256x256.npy").is_file()
    plate = np.asarray(load_plate(entry), np.int16)
    frames = [np.asarray(f, np.int16) for f in read_frames(root / "zero.mp4")]
    # The person is drawn over the scene in every frame: his own pixels, well away from the plate's.
    changed = [(np.abs(f - plate).max(axis=2) > 40).sum() for f in frames]
    assert min(changed) > 300, changed

    assert _dance(song, clip, cache, root / "a.mp4", "0.05") == 0
    assert "VGG perceptual loss is OFF" in capsys.readouterr().err
    info = probe_video(root / "a.mp4")
    assert (info.width, info.height) == (640, 360) and info.fps == pytest.approx(30)
    assert probe_streams(root / "a.mp4")["audio_codec"] == "aac"
    first = _meta(entry)
    assert first["step"] > 0 and first["trained_seconds"] >= 3 - 1 and (entry / "background.png").is_file()

    # A cached model renders at once (its time: benchmarks/bench_dance.py --target): no step, no checkpoint.
    assert _dance(song, clip, cache, root / "b.mp4", "0.05") == 0
    assert _meta(entry) == first, "the cached model was used as it was"

    # 3 s past what the first call trained: its last step may overrun its budget far on a busy CPU.
    minutes = first["trained_seconds"] / 60 + 0.05
    assert _dance(song, clip, cache, root / "c.mp4", f"{minutes:.4f}") == 0
    more = _meta(entry)
    assert more["step"] > first["step"] and more["trained_seconds"] >= 60 * minutes - 1, (first, more["step"])


def test_bad_targets_are_one_sentence_errors(setup, tmp_path, capsys):
    _, clip, song, cache = setup
    short = tmp_path / "short.mp4"
    write_video(short, [np.full((64, 64, 3), 90, np.uint8)] * 30, 15.0)
    not_video = tmp_path / "notes.mp4"
    not_video.write_text("not a video")
    empty = tmp_path / "empty.mp4"
    rng = np.random.default_rng(0)
    write_video(empty, [rng.integers(0, 255, (96, 128, 3), np.uint8) for _ in range(60)], 15.0)
    for target, words in ((short, "lasts 2.0 s"), (not_video, "notes.mp4"), (empty, "No person was found")):
        assert _dance(song, target, tmp_path / "cache", tmp_path / "x.mp4", "0.05") == 1
        err = capsys.readouterr().err
        assert err.startswith("dancesynth dance: error:") and "Traceback" not in err and words in err, err
        assert err.count("\n") == 1
        assert not (tmp_path / "x.mp4").exists()
