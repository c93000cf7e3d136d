"""Real footage benchmark: the appearance model on a real outdoor clip, and `dance --target` on it.

The clip is the demo video of the PyPI package ``sports2d`` (BSD-3-Clause, (c) perfanalytics): 7.7 s,
1768x994, 30 fps, a fixed camera, two people (one jumping on a box, one walking by); the tracker keeps one.

    python benchmarks/real_footage.py fetch            # pip download sports2d (no dependencies) into the cache
    python benchmarks/real_footage.py run --minutes 10 --presets small medium

``run`` trains (or reuses, through the appearance cache of `dance --target`) one model per preset for
``--minutes``, then prints per preset: training minutes and steps, held-out SSIM / PSNR at model resolution,
PCK@0.1 of BlazePose run on the held-out frames of the whole scene (the generated crops composited into it, and
the real frames, the ceiling) against the commanded poses, and the wall time of `dance --target` for a
``--dance-seconds`` segment of a real song with the cached model (training excluded; decoding, generation,
compiling the renderer, rendering, compositing and encoding at the clip's resolution included) and the frames per
second of its frame loop (rendering, compositing and encoding; above the clip's 30 fps is real time). It writes
``docs/real_footage/<preset>.png``: held-out frames, real | composited into the scene, and frames of the dance.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import cv2
import numpy as np
from eval_video import extracted, held_out_quality

from apps.pipeline import dance
from dancesynth.core.checkpoint import load_meta
from dancesynth.core.media import read_frames
from stage2_video.cache import appearance_model_for
from stage2_video.composite import scene_compositor
from stage2_video.quality import pck
from stage2_video.render import load_appearance_model
from stage2_video.train import KIND

PACKAGE = "sports2d==0.8.34"
MEMBERS = {"Sports2D/Demo/demo.mp4": "demo.mp4", "sports2d-0.8.34.dist-info/licenses/LICENSE": "LICENSE"}
DEFAULT_CACHE = Path.home() / ".cache" / "dancesynth" / "real-footage"
REPO = Path(__file__).resolve().parent.parent
SONG = REPO / "tests" / "data" / "real_song" / "escape_from_chaosland_40-65s.ogg"


def fetch(cache: Path) -> Path:
    """Download the sports2d wheel (no dependencies) and extract the clip and its licence into ``cache``."""
    cache.mkdir(parents=True, exist_ok=True)
    subprocess.run([sys.executable, "-m", "pip", "download", PACKAGE, "--no-deps", "-d", str(cache)], check=True)
    wheel = next(cache.glob("sports2d-*.whl"))
    with zipfile.ZipFile(wheel) as z:
        for member, name in MEMBERS.items():
            (cache / name).write_bytes(z.read(member))
    return cache / "demo.mp4"


def strip(images: list[np.ndarray], height: int = 240) -> np.ndarray:
    """Images side by side, each scaled to ``height`` pixels."""
    return np.concatenate([cv2.resize(im, (round(im.shape[1] * height / im.shape[0]), height),
                                      interpolation=cv2.INTER_AREA) for im in images], axis=1)


def composited_frames(run: Path, scored) -> list[np.ndarray]:
    """The generated frames of ``scored`` (:class:`eval_video.HeldOut`) composited into the whole scene."""
    compositor = scene_compositor(run, load_appearance_model(run, "cpu", optimize=False).canvas)
    return [compositor.frame(g, kp, f) for g, kp, f in zip(scored.generated, scored.commanded.keypoints,
                                                            scored.framings)]


def contact_sheet(reals: list[np.ndarray], composited: list[np.ndarray], dance_video: Path, out: Path,
                  count: int = 3) -> None:
    """Rows: real held-out frame | the model's frame composited into the scene; last two rows: frames of the dance."""
    rows = [strip([reals[i], composited[i]]) for i in np.linspace(0, len(reals) - 1, count).astype(int)]
    dance_frames = list(read_frames(dance_video))
    picks = [dance_frames[i] for i in np.linspace(0, len(dance_frames) - 1, 4).astype(int)]
    rows += [strip(picks[:2]), strip(picks[2:])]
    out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out), cv2.cvtColor(np.concatenate(rows), cv2.COLOR_RGB2BGR))


def run(args: argparse.Namespace) -> None:
    clip = args.cache / "demo.mp4"
    if not clip.is_file():
        raise SystemExit(f"{clip} is missing; run `python benchmarks/real_footage.py fetch` first.")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for preset in args.presets:
            start = time.perf_counter()
            run_dir = appearance_model_for(clip, args.minutes, preset, args.model_cache)
            trained = time.perf_counter() - start
            held_out = held_out_quality(run_dir, device="cpu")
            out = Path(tmp) / f"{preset}.mp4"
            start = time.perf_counter()
            made = dance(SONG, out, target=clip, cache=args.model_cache, train_minutes=args.minutes,
                         preset=preset, duration=args.dance_seconds, device="cpu")
            dance_s = time.perf_counter() - start
            reals = [frame for t, frame in enumerate(read_frames(clip)) if t in held_out.frames]
            composited = composited_frames(run_dir, held_out)
            contact_sheet(reals, composited, out, args.sheets / f"{preset}.png")
            fps = held_out.commanded.fps
            scene = [pck(extracted(frames, fps), held_out.commanded) for frames in (composited, reals)]
            seen = held_out_quality(run_dir, device="cpu", training_frames=True)
            seen_scene = pck(extracted(composited_frames(run_dir, seen), fps), seen.commanded)
            meta = load_meta(run_dir, KIND)
            rows.append((preset, meta["trained_seconds"] / 60, meta["step"], held_out.ssim, held_out.psnr,
                         *scene, seen.ssim, seen_scene, trained, dance_s, len(made.poses) / made.render_seconds))
    print(f"clip {clip}: {args.minutes:g} min per model; dance segment {args.dance_seconds:g} s of {SONG.name}")
    print("SSIM / PSNR: held-out frames at model resolution; PCK@0.1: BlazePose on the held-out frames of the whole")
    print("scene (composited | real, the ceiling) vs the commanded poses; 'seen': the same on as many of the last")
    print("training frames (learnt vs generalised); call s: this run's first call (0 if cached)")
    print(f"{'preset':<8} {'train min':>9} {'steps':>6} {'SSIM':>6} {'PSNR dB':>8} {'PCK gen':>8} {'PCK real':>9} "
          f"{'SSIM seen':>9} {'PCK seen':>8} {'call s':>7} {'dance s':>8} {'x real time':>11} {'render fps':>10}")
    for preset, minutes, steps, s, p, pg, pr, ss, ps, call, d, fps in rows:
        print(f"{preset:<8} {minutes:9.1f} {steps:6d} {s:6.3f} {p:8.2f} {pg:8.3f} {pr:9.3f} {ss:9.3f} {ps:8.3f} "
              f"{call:7.0f} {d:8.1f} {args.dance_seconds / d:11.2f} {fps:10.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("command", choices=("fetch", "run"))
    ap.add_argument("--cache", type=Path, default=DEFAULT_CACHE, help="where the clip is kept")
    ap.add_argument("--model-cache", type=Path, default=None,
                    help="appearance-model cache (default: dance --target's, under ~/.cache/dancesynth)")
    ap.add_argument("--minutes", type=float, default=10.0, help="training minutes per model (default 10)")
    ap.add_argument("--presets", nargs="+", default=["small", "medium"])
    ap.add_argument("--dance-seconds", type=float, default=20.0)
    ap.add_argument("--sheets", type=Path, default=REPO / "docs" / "real_footage")
    args = ap.parse_args()
    if args.command == "fetch":
        print(f"wrote {fetch(args.cache)}")
    else:
        run(args)


if __name__ == "__main__":
    main()
