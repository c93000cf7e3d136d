"""`dancesynth demo`: from nothing to a dancing video with the song's audio, a summary and a time budget."""

import json
from pathlib import Path

import pytest
import torch

torch.set_num_threads(1)

from apps.cli import main  # noqa: E402
from apps.demo import DemoPlan, run_demo  # noqa: E402
from dancesynth.core.media import probe_streams, probe_video  # noqa: E402

# The demo's own steps at toy sizes: 6 songs of 12 s, a 4-s target video, a 3-s dance; of a 1.2-minute budget the
# finishing steps' share leaves the training what the steps before it left of 0.15 minutes (at least 0.05).
TOY = DemoPlan(clips=6, clip_seconds=12.0, target_seconds=4.0, target_size=128, dance_seconds=3.0,
               finish_minutes=1.05, min_train_minutes=0.05, preset="small")


def _snapshot(folder: Path, parts: tuple[str, ...]) -> dict[str, int]:
    """Modification time (ns) of each file under ``folder``'s sub-folders ``parts``."""
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for part in parts for p in (folder / part).rglob("*")
            if p.is_file()}


def test_demo_writes_a_dance_with_the_song_summary_and_pictures_within_its_budget(tmp_path):
    """(Its time against the budget, and a rerun's: ``benchmarks/bench_dance.py --demo``.)"""
    written = run_demo(tmp_path / "demo", minutes=1.2, device="cpu", plan=TOY)
    names = {p.name for p in written}
    assert {"dance.mp4", "skeleton.mp4", "side_by_side.mp4", "summary.md"} <= names
    streams = probe_streams(tmp_path / "demo" / "dance.mp4")
    assert streams["video_codec"] == "h264" and streams["audio_codec"] == "aac"
    # The whole scene of the target video (its canvas), not the model's 128-px crop.
    target, dance = (probe_video(tmp_path / "demo" / name) for name in ("target/target.mp4", "dance.mp4"))
    assert (dance.width, dance.height) == (target.width, target.height)
    assert streams["video_duration"] == pytest.approx(TOY.dance_seconds, abs=1 / streams["fps"])
    assert streams["audio_duration"] == pytest.approx(TOY.dance_seconds, abs=1 / streams["fps"])
    summary = (tmp_path / "demo" / "summary.md").read_text()
    assert "beat hit rate" in summary and "SSIM" in summary and "| real dance |" in summary
    assert (tmp_path / "demo" / "frames.png").stat().st_size > 0
    # Training gets what the budget leaves after the steps before it and the finishing steps' share.
    budget = json.loads((tmp_path / "demo" / "runs" / "video_minutes.json").read_text())["minutes"]
    assert TOY.min_train_minutes <= budget < 1.2 - TOY.finish_minutes, budget

    kept = _snapshot(tmp_path / "demo", ("dataset", "target", "runs"))
    run_demo(tmp_path / "demo", minutes=1.2, device="cpu", plan=TOY)
    assert _snapshot(tmp_path / "demo", ("dataset", "target", "runs")) == kept, \
        "a finished demo's models and data are reused, not remade or retrained"


def test_too_small_budget_is_a_clear_error(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "d"), "--minutes", "1"]) == 1
    err = capsys.readouterr().err
    assert "--minutes must be more than 1" in err and "Traceback" not in err
    assert not (tmp_path / "d" / "dance.mp4").exists()
