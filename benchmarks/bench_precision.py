"""Training and rendering speed of the appearance model per precision, on this machine's CPU.

For the small preset's network at each ``--sizes`` resolution, prints in one table:
  * the seconds per training step (a batch of consecutive-frame pairs: generator, both discriminators, their
    updates) of `dancesynth train-video` in fp32 and under bf16 autocast, from its losses.csv, on a synthetic
    target person (:mod:`stage2_video.synthetic_person`); the first step (warm-up) is not counted;
  * the rendering frames/s of the OpenVINO generator (random weights; speed does not depend on them) in f32
    with Winograd residual blocks (the fp32 path), f32 with direct convolutions, bf16 with direct convolutions
    (the bf16 path) and bf16 with Winograd blocks, timed in interleaved rounds as in ``bench_render.py``
    (median round), with each one's largest 0-255 difference to the plain fp32 PyTorch forward on identical
    inputs.
On a CPU without AMX or AVX-512-BF16, `train-video` refuses bf16 (its column is empty) and OpenVINO ignores
its bf16 hint (the header says what it offers).

With ``--ssim-minutes M`` it then trains two models on the same target video (the synthetic person, or
``--video``) for M minutes each, in fp32 and in ``auto`` precision, and prints their held-out SSIM / PSNR.

    python benchmarks/bench_precision.py                          # the speed table (about 3 minutes on 2 cores)
    python benchmarks/bench_precision.py --ssim-minutes 15        # + held-out SSIM after 15 min each
    python benchmarks/bench_precision.py --ssim-minutes 15 --video person.mp4 --ssim-size 128
"""

from __future__ import annotations

import argparse
import csv
import platform
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import openvino
import torch
from bench_render import dancing_poses, interleaved_fps, max_step_diff, scene_plate
from eval_video import held_out_quality

from dancesynth.core.device import cpu_has_bf16, precision_name, resolve_device, resolve_precision
from dancesynth.core.skeleton import PoseSequence, resample
from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_dance import synthesize_dance
from stage2_video.framing import whole_canvas
from stage2_video.models.pix2pixhd import Pix2PixHD, generator_channels, preset
from stage2_video.render import AppearanceModel, OpenVINOGenerator
from stage2_video.synthetic_person import appearance_preset, write_person_video
from stage2_video.train import TrainOptions, train_video

# (column title, OpenVINO precision, Winograd residual blocks)
RENDER_PATHS = [("f32 Winograd", torch.float32, True), ("f32 direct", torch.float32, False),
                ("bf16 direct", torch.bfloat16, False), ("bf16 Winograd", torch.bfloat16, True)]


def cpu_name() -> str:
    """The CPU's model name (Linux), else what :mod:`platform` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.partition(":")[2].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def synthetic_target(folder: Path, seconds: float, height: int = 256, fps: float = 30.0) -> tuple[Path, Path]:
    """(video.mp4, poses.npz): the synthetic person dancing for ``seconds`` at ``fps``, ``height`` px high
    (``height`` even)."""
    beats = np.arange(0.0, seconds, 0.5)
    seq = synthesize_dance(STYLES[next(iter(STYLES))], beats, int(seconds * 15), np.random.default_rng(0), fps=15)
    seq = resample(seq, fps)
    s = height / seq.height
    # H.264 wants an even width.
    seq = PoseSequence(seq.keypoints * (s, s, 1), seq.fps, 2 * round(seq.width * s / 2), height)
    video, poses = folder / "target.mp4", folder / "target_poses.npz"
    seq.save(poses)
    write_person_video(seq, video, appearance_preset("red_tee"))
    return video, poses


def step_seconds(video: Path, poses: Path, run_dir: Path, size: int, precision: str, steps: int) -> float:
    """Median seconds per training step after the first, of ``steps`` steps of `train-video` at ``size`` px."""
    train_video(video, run_dir, "small", TrainOptions(epochs=1, max_steps=steps, val_frames=1, checkpoint_every=10**9,
                                                      sample_every=10**9),
                poses=poses, device="cpu", overrides={"width": size, "height": size}, precision=precision)
    with open(run_dir / "losses.csv", newline="") as f:
        seconds = [float(row["seconds"]) for row in csv.DictReader(f)]
    return float(np.median(np.diff(seconds)))


def render_rows(size: int, frames: int, rounds: int) -> list[tuple[float, int]]:
    """(median frames/s, max |difference| to plain fp32) of each of :data:`RENDER_PATHS` at ``size`` px."""
    config = preset("small", width=size, height=size)
    torch.manual_seed(0)
    generator = Pix2PixHD(config).generator.eval()
    framing, device = whole_canvas(size, size, size, size), torch.device("cpu")
    poses = dancing_poses(frames, size)

    def wrap(network: Callable[[torch.Tensor], torch.Tensor]) -> AppearanceModel:
        return AppearanceModel(network, config, framing, None, 15.0, device, (size, size),
                               plate=scene_plate(config, size))

    plain = wrap(generator)
    channels = generator_channels(config)
    models = [wrap(OpenVINOGenerator(generator, channels, size, size, dtype, winograd))
              for _, dtype, winograd in RENDER_PATHS]
    runs = interleaved_fps(models, poses, rounds)
    return [(float(np.median(fps)), max_step_diff(plain, fast, poses)) for fps, fast in zip(runs, models)]


def compare_precisions(video: Path, poses: Path | None, folder: Path, size: int, minutes: float) -> None:
    """Train fp32 and auto-precision models for ``minutes`` each on ``video``; print their held-out scores, each
    rendered in the precision it was trained in (:func:`eval_video.held_out_quality`)."""
    print(f"\nheld-out quality after {minutes:g} min of training each, {size} px, target {video}:")
    print(f"{'precision':<16}{'steps':>7}{'SSIM':>8}{'PSNR dB':>9}{'PCK':>7}")
    for name in ("fp32", "auto"):
        run = folder / f"ssim_{name}"
        meta = train_video(video, run, "small", TrainOptions(minutes=minutes), poses=poses, device="cpu",
                           overrides={"width": size, "height": size}, precision=name)
        scores = held_out_quality(run, device="cpu", precision=name)
        label = name if name == "fp32" else f"auto = {meta['precision']}"
        pck = dict(scores.pck)["generated vs commanded"]
        print(f"{label:<16}{meta['step']:>7}{scores.ssim:>8.3f}{scores.psnr:>9.2f}{pck:>7.3f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", type=int, default=[128, 256])
    parser.add_argument("--steps", type=int, default=3, help="training steps per precision (the first is warm-up)")
    parser.add_argument("--frames", type=int, default=8, help="frames per rendering round")
    parser.add_argument("--rounds", type=int, default=3, help="timed rendering rounds per path (median reported)")
    parser.add_argument("--threads", type=int, help="torch and OpenVINO CPU threads (default: torch's choice)")
    parser.add_argument("--ssim-minutes", type=float, help="also train fp32 and auto models this long each")
    parser.add_argument("--ssim-size", type=int, default=256, help="model resolution of the SSIM comparison")
    parser.add_argument("--video", type=Path, help="target video of the SSIM comparison (default: synthetic)")
    parser.add_argument("--seconds", type=float, default=20.0, help="length of the synthetic target video")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    capabilities = openvino.Core().get_property("CPU", "OPTIMIZATION_CAPABILITIES")
    print(f"{cpu_name()}; bf16 instructions (AMX/AVX-512-BF16): {cpu_has_bf16()}; "
          f"OpenVINO {openvino.__version__} offers {', '.join(capabilities)}; torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads; auto precision here: "
          f"{precision_name(resolve_precision('auto', resolve_device('cpu')))}.")
    print("The CPU may be shared with other jobs: compare within a row; absolute numbers vary with their load.")
    titles = [title for title, _, _ in RENDER_PATHS]
    print(f"{'size':>5}{'step fp32 s':>13}{'step bf16 s':>13}{'speed-up':>10}"
          + "".join(f"{t + ' fps':>18}" for t in titles) + "".join(f"{t + ' diff':>19}" for t in titles))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        video, poses = synthetic_target(folder, args.seconds)
        for size in args.sizes:
            times = [step_seconds(video, poses, folder / f"steps_{name}_{size}", size, name, args.steps)
                     if name == "fp32" or cpu_has_bf16() else np.nan for name in ("fp32", "bf16")]
            rendered = render_rows(size, args.frames, args.rounds)
            print(f"{size:>5}{times[0]:>13.2f}{times[1]:>13.2f}{times[0] / times[1]:>10.2f}"
                  + "".join(f"{fps:>18.2f}" for fps, _ in rendered)
                  + "".join(f"{diff:>19d}" for _, diff in rendered), flush=True)
        if args.ssim_minutes:
            if args.video is not None:
                video, poses = args.video, None
            compare_precisions(video, poses, folder, args.ssim_size, args.ssim_minutes)


if __name__ == "__main__":
    main()
