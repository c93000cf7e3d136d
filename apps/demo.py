"""`dancesynth demo`: from nothing to a dancing video within a time budget, on the built-in data.

Steps (each skipped when its output already exists, so an interrupted demo continues where it stopped):
a few built-in songs -> synthetic target-person video -> appearance model (every minute of the budget but the
dance step's) -> the shipped pose model dances a held-out song, composited into the target's scene at its
resolution (dance video, skeleton video, side-by-side) -> summary page with metrics and frames.
"""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from apps.pipeline import dance
from apps.requests import DanceRequest
from dancesynth.core.checkpoint import load_meta
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.media import SONG_SAMPLE_RATE, load_song, read_frames
from dancesynth.core.motion import kinematic_beats, mean_speed
from dancesynth.core.skeleton import PoseSequence, body_scale, resample
from stage1_pose.data.dataset import Clip, DanceDataset
from stage1_pose.data.make_dataset import make_dataset
from stage1_pose.generate import generate_dance, load_pose_model
from stage1_pose.metrics import beat_align_score, beat_coverage, beat_hit_rate
from stage1_pose.pretrained import DEFAULT_POSE_MODEL, TRAINING_DATA_SEED
from stage2_video.model_cache import train_for
from stage2_video.presets import resolve_preset
from stage2_video.synthetic_person import appearance_preset, write_person_video
from stage2_video.training_data import rendered_checkpoint

logger = logging.getLogger(__name__)
# The synthetic target's look (stage2_video.synthetic_person); benchmarks draw the truth of its dances in it.
DEMO_LOOK = "red_tee"

@dataclass(frozen=True)
class DemoPlan:
    """Sizes and time budget of the demo: the appearance model trains until ``finish_minutes`` before the
    deadline (the dance step's time), at least ``min_train_minutes``, at ``preset`` (``auto``: 256 px where
    the hardware makes it affordable). ``clips`` built-in songs of ``clip_seconds`` give the target's dance (a
    training song) and the song danced to (a held-out one)."""

    clips: int = 10
    clip_seconds: float = 60.0
    finish_minutes: float = 2.0
    min_train_minutes: float = 0.5
    target_seconds: float = 60.0
    target_size: int = 512
    dance_seconds: float = 20.0
    preset: str = "auto"


def _mean_speed(seq: PoseSequence) -> float:
    """Mean joint speed in torso lengths per second (scale-free, so real and generated dances compare)."""
    return mean_speed(seq.xy, seq.fps, unit_length=body_scale(seq))


def dance_metrics(seq: PoseSequence, beats: np.ndarray) -> dict[str, float]:
    """Beat metrics of a dance against music beat times (seconds), plus its mean joint speed."""
    k = kinematic_beats(seq.xy, seq.fps)
    m = beats[beats < seq.duration] * seq.fps
    return {"beat coverage": beat_coverage(k, m), "beat hit rate": beat_hit_rate(k, m),
            "beat align score": beat_align_score(m / seq.fps, k / seq.fps), "speed (torso/s)": _mean_speed(seq)}


def liveliest(dataset: DanceDataset, clips: list[Clip]) -> Clip:
    """The clip whose real dance moves most: its song makes the demo, where motion is easiest to judge by eye."""
    return max(clips, key=lambda clip: _mean_speed(dataset.load_poses(clip)))


def _contact_sheet(video: Path, out: Path, count: int = 6) -> None:
    """A PNG strip of ``count`` frames spread over ``video``."""
    import cv2

    frames = list(read_frames(video))
    picks = [frames[i] for i in np.linspace(0, len(frames) - 1, count).astype(int)]
    scale = 256 / picks[0].shape[0]
    strip = np.concatenate([cv2.resize(f, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA) for f in picks],
                           axis=1)
    with atomic_path(out) as tmp:
        cv2.imwrite(str(tmp), cv2.cvtColor(strip, cv2.COLOR_RGB2BGR))


def run_demo(out: str | os.PathLike = "demo_output", minutes: float = 15.0, seed: int = 0, device: str = "auto",
             plan: DemoPlan | None = None) -> list[Path]:
    """Run every demo step under the folder ``out`` within about ``minutes`` minutes of wall-clock time, with the
    random ``seed`` on ``device`` (``auto``, ``cpu`` or ``cuda``), at ``plan``'s sizes (None: ``DemoPlan()``);
    returns the files written."""
    if minutes <= 1:
        raise DancesynthError("--minutes must be more than 1; the demo needs time to train the appearance model.")
    plan = plan or DemoPlan()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    clock = time.monotonic()
    deadline = clock + minutes * 60.0

    def step(name: str) -> None:
        nonlocal clock
        now = time.monotonic()
        timings[name] = now - clock
        clock = now
        logger.info(f"[demo] {name}: {timings[name]:.0f} s")

    data_dir = out / "dataset"
    if not (data_dir / "manifest.json").is_file():
        # Songs the shipped pose model never heard.
        make_dataset(data_dir, clips=plan.clips, seconds=plan.clip_seconds, seed=TRAINING_DATA_SEED + 1 + seed)
    dataset = DanceDataset(data_dir)
    step("built-in songs")

    # The target person dances one song, the dance is made for another.
    target_dir = out / "target"
    target_video, target_poses = target_dir / "target.mp4", target_dir / "target_poses.npz"
    if not target_video.is_file():
        target_dir.mkdir(exist_ok=True)
        clip = dataset.clips("train")[0]
        seq = dataset.load_poses(clip)
        seq = resample(seq.slice_frames(0, int(plan.target_seconds * seq.fps)), 30.0)
        s = plan.target_size / seq.height
        seq = PoseSequence(seq.keypoints * (s, s, 1), seq.fps, round(seq.width * s), plan.target_size)
        seq.save(target_poses)
        write_person_video(seq, target_video, appearance_preset(DEMO_LOOK))
    step("synthetic target video")

    video_run = out / "runs" / "video"
    preset = resolve_preset(plan.preset, device)
    # The budget is fixed on the first run, so an interrupted demo resumes the training for the minutes it lacks.
    budget_file = out / "runs" / "video_minutes.json"
    if not budget_file.is_file():
        budget_file.parent.mkdir(parents=True, exist_ok=True)
        minutes_left = (deadline - plan.finish_minutes * 60.0 - time.monotonic()) / 60.0
        with atomic_path(budget_file) as tmp:
            tmp.write_text(json.dumps({"minutes": max(plan.min_train_minutes, minutes_left)}))
    train_for(target_video, video_run, json.loads(budget_file.read_text())["minutes"], preset, device,
              poses=target_poses)
    step(f"appearance model ({preset})")

    clip = liveliest(dataset, dataset.clips("test"))
    song = data_dir / clip.audio
    written = dance(DanceRequest(song=song, out=out / "dance.mp4", video_model=video_run, seed=seed,
                                 duration=plan.dance_seconds, skeleton_preview=out / "skeleton.mp4",
                                 side_by_side=out / "side_by_side.mp4", device=device)).written
    step("dance for a held-out song")

    written.append(_summary(out, dataset, clip, video_run, timings, seed, device, plan))
    return written


def _summary(out: Path, dataset: DanceDataset, clip: Clip, video_run: Path, timings: dict[str, float], seed: int,
             device: str, plan: DemoPlan) -> Path:
    seconds = plan.dance_seconds
    beats = np.array(json.loads((dataset.root / clip.beats).read_text())["beats"])
    samples = load_song(dataset.root / clip.audio, SONG_SAMPLE_RATE)[: int(seconds * SONG_SAMPLE_RATE)]
    model = load_pose_model(DEFAULT_POSE_MODEL, device)
    generated = generate_dance(model, samples, SONG_SAMPLE_RATE, seed=seed)
    real = dataset.load_poses(clip).slice_frames(0, len(generated))
    rows = {f"generated ({model.meta['method']}, shipped model)": dance_metrics(generated, beats),
            "real dance": dance_metrics(real, beats)}
    _contact_sheet(out / "side_by_side.mp4", out / "frames.png")
    meta = load_meta(video_run, "stage2")
    val = rendered_checkpoint(meta)
    lines = [
        "# dancesynth demo", "",
        f"Held-out song `{clip.id}` (style {clip.style}), first {seconds:g} s, seed {seed}, device {device}.", "",
        "Files: [dance.mp4](dance.mp4) · [skeleton.mp4](skeleton.mp4) · [side_by_side.mp4](side_by_side.mp4) · "
        "[target video](target/target.mp4)", "",
        "![skeleton | generated person](frames.png)", "",
        "## Stage 1: the generated dance against the real dance for this song", "",
        "| dance | " + " | ".join(next(iter(rows.values()))) + " |",
        "|---|" + "---|" * len(next(iter(rows.values()))),
    ]
    lines += [f"| {name} | " + " | ".join(f"{v:.3f}" for v in r.values()) + " |" for name, r in rows.items()]
    lines += ["", "Beat coverage = kinematic beats / music beats; hit rate = share of kinematic beats within "
              "±2 frames of a music beat; align score = Bailando's BAS (σ = 50 ms). See the README's metrics section.",
              "", "## Stage 2: held-out frames of the target video", ""]
    if "ssim" in val:
        lines += [f"SSIM {float(val['ssim']):.3f}, PSNR {float(val['psnr']):.2f} dB at step {val['step']}, the "
                  "checkpoint the dance was rendered with."]
    lines += ["", "Training curve: [appearance model](runs/video/losses.png)", "",
              "## Time per step", "", "| step | seconds |", "|---|---|"]
    lines += [f"| {k} | {v:.0f} |" for k, v in timings.items()]
    path = out / "summary.md"
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return path
