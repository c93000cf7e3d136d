"""The GPU path, ready to check: every trainer's ``paper`` preset for a few steps on CUDA, then ``dance`` with a
256-px appearance model, as one table.

Trainers: each stage-1 method of :mod:`stage1_pose.registry`, the ST-GCN behind Ren et al.'s perceptual loss (the
ren row uses the ST-GCN just trained), the style classifier, and the appearance model (pix2pixHD) at ``paper``
and at 256 px (``medium``); the ``dance`` row renders a synthetic song with that 256-px model. The data are
synthetic: a built-in song and dance (:mod:`stage1_pose.data.synth_music`, ``synth_dance``) and the synthetic
person dancing it (:mod:`stage2_video.synthetic_person`).

Columns:
  * steps/s: the median over the steps after the first (warm-up) of one update (forward, losses, backward,
    optimizer steps) on a batch held on the device; data loading is not timed. The dance row: frames/s of the
    whole ``dancesynth.dance`` call (song analysis, dance, loading, rendering, encoding).
  * peak MiB: the most GPU memory torch held during the row.
  * max |GPU - CPU|: the largest difference of a forward pass to the same weights' float32 forward on the CPU:
    stage 1 a generated window (same noise), the classifiers their logits, the appearance model a generated
    frame in [-1, 1] (2/255 is one grey level), the dance row the render path's compiled generator.
  * precision: what the trainer computes in. The appearance model trains under autocast (bf16 on GPUs that have
    it, else fp16 with loss scaling; :func:`dancesynth.core.device.resolve_precision`); the stage-1 trainer, the
    ST-GCN's and the style classifier's loops have no autocast and train in float32.

The paper appearance model uses pix2pixHD's VGG loss; without ``--vgg-weights`` the VGG19 gets random weights
(the same time and memory; nothing is downloaded). A row that fails shows its error and the script exits 1.

    python benchmarks/gpu_check.py                                  # 20 steps each on the GPU
    python benchmarks/gpu_check.py --vgg-weights vgg19.pth --steps 50
    python benchmarks/gpu_check.py --device cpu --steps 2 --tiny    # the smoke test (toy sizes, CPU)

Without a CUDA GPU (and without --device cpu) it prints one line and exits 0.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import soundfile
import torch
import torch.nn.functional as F

import dancesynth
from dancesynth.core.config import config_to_dict
from dancesynth.core.device import precision_name, resolve_precision
from dancesynth.core.runs import RunFolder
from dancesynth.core.skeleton import PoseSequence, normalize
from stage1_pose.data.layout import POSE_FPS
from stage1_pose.data.styles import STYLES
from stage1_pose.data.synth_dance import synthesize_dance
from stage1_pose.data.synth_music import Song, synthesize_song
from stage1_pose.models.base import Batch
from stage1_pose.models.ren.perceptual import CHECKPOINT_KIND as STGCN_KIND
from stage1_pose.models.ren.stgcn import STGCN, STGCN_PRESETS
from stage1_pose.music_features import feature_dim
from stage1_pose.registry import build_method, make_config, method_names
from stage1_pose.style_classifier import INPUT_DIM, StyleClassifier
from stage1_pose.style_classifier import PRESETS as STYLE_PRESETS
from stage2_video.models.pix2pixhd import Pix2PixHD, generator_channels
from stage2_video.render import load_appearance_model
from stage2_video.synthetic_person import appearance_preset, write_person_video
from stage2_video.train import TrainOptions, VideoTrainer, video_trainer

# --tiny: each family's CPU preset cut to a batch of two, and the appearance models to toy networks.
TINY_BATCH = {"batch_size": 2}
TINY_PIX2PIXHD = {"paper": {"width": 64, "height": 32, "ngf": 4, "n_downsample": 1, "n_blocks": 1,
                            "n_blocks_local": 1, "ndf": 4, "n_layers_d": 1, "num_d": 1},
                  "medium": {"width": 32, "height": 32, "ngf": 4, "n_downsample": 1, "n_blocks": 1, "ndf": 4,
                             "batch_size": 2}}
SONG_SECONDS = {False: 8.0, True: 2.0}  # the synthetic song and the person's video (--tiny: 2 s)


@dataclass
class Row:
    name: str
    preset: str
    precision: str = "fp32"
    rate: float = float("nan")
    unit: str = "steps/s"
    peak_mib: float | None = None
    difference: float = float("nan")
    error: str = ""


def synchronize(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def steps_per_second(step: Callable[[], object], steps: int, device: torch.device) -> float:
    """Median rate of ``step`` over the calls after the first (the first builds kernels and caches)."""
    times = []
    for _ in range(steps):
        synchronize(device)
        start = time.perf_counter()
        step()
        synchronize(device)
        times.append(time.perf_counter() - start)
    return 1.0 / statistics.median(times[1:] or times)


def largest_difference(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a.detach().float().cpu() - b.detach().float().cpu()).abs().max())


def measured(row: Row, device: torch.device, work: Callable[[Row], None]) -> Row:
    """``work`` fills ``row``; its peak GPU memory is recorded, and an exception becomes the row's error."""
    if device.type == "cuda":
        torch.cuda.empty_cache()
        torch.cuda.reset_peak_memory_stats(device)
    try:
        work(row)
    except Exception as e:  # noqa: BLE001 - the check reports every failing path, not only the first
        traceback.print_exc()
        row.error = f"{type(e).__name__}: {e}".splitlines()[0][:100]
    if device.type == "cuda":
        row.peak_mib = torch.cuda.max_memory_allocated(device) / 2**20
    return row


# --- synthetic data -----------------------------------------------------------------------------------------------
def song_and_dance(seconds: float) -> tuple[Song, PoseSequence]:
    rng = np.random.default_rng(0)
    style = STYLES["pop"]
    song = synthesize_song(style, seconds, rng)
    return song, synthesize_dance(style, song.beats, int(seconds * POSE_FPS), rng)


def window_poses(dance: PoseSequence, batch: int, frames: int) -> torch.Tensor:
    """``[batch, frames, 25, 2]`` model coordinates: the dance repeated to ``frames``, in each row from another
    start."""
    xy = torch.from_numpy(normalize(dance)[0]).float()
    index = (torch.arange(frames)[None] + 7 * torch.arange(batch)[:, None]) % len(xy)
    return xy[index]


def stage1_batch(feature_kind: str, batch: int, frames: int, dance: PoseSequence, beats: np.ndarray) -> Batch:
    """A batch of the shapes the stage-1 trainer feeds: standardised features (random here: the step's cost
    does not depend on their values), the song's beats on pose frames, the dance's poses, style 0."""
    g = torch.Generator().manual_seed(0)
    features = torch.randn(batch, frames, feature_dim(feature_kind, POSE_FPS), generator=g)
    on_beat = torch.zeros(batch, frames, dtype=torch.bool)
    on_beat[:, np.round(beats * POSE_FPS).astype(int) % frames] = True
    return Batch(features, on_beat, window_poses(dance, batch, frames), torch.zeros(batch, dtype=torch.long))


# --- stage 1 ------------------------------------------------------------------------------------------------------
def stgcn_row(args: argparse.Namespace, device: torch.device, dance: PoseSequence, run: Path) -> Row:
    """The ST-GCN's update (cross-entropy over styles, Adam); saved to ``run`` for the ren method's loss."""
    preset = "small" if args.tiny else "paper"

    def work(row: Row) -> None:
        config = STGCN_PRESETS[preset].with_classes(len(STYLES))
        if args.tiny:
            config = dataclasses.replace(config, **TINY_BATCH)
        torch.manual_seed(0)
        net = STGCN(config).to(device)
        opt = torch.optim.Adam(net.parameters(), lr=config.lr)
        poses = window_poses(dance, config.batch_size, config.window_frames).to(device)
        style = torch.zeros(config.batch_size, dtype=torch.long, device=device)

        def step() -> None:
            loss = F.cross_entropy(net(poses), style)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()

        row.rate = steps_per_second(step, args.steps, device)
        folder = RunFolder(run, STGCN_KIND, device)
        folder.save(net, {"config": config_to_dict(config), "step": args.steps}, {"adam": opt})
        folder.close()
        row.difference = classifier_difference(net, STGCN(config), poses[:2])

    return measured(Row("ST-GCN (ren's loss)", preset), device, work)


def style_classifier_row(args: argparse.Namespace, device: torch.device) -> Row:
    preset = "small" if args.tiny else "paper"

    def work(row: Row) -> None:
        config = STYLE_PRESETS[preset]
        if args.tiny:
            config = dataclasses.replace(config, **TINY_BATCH)
        torch.manual_seed(0)
        net = StyleClassifier(config, len(STYLES)).to(device)
        opt = torch.optim.Adam(net.parameters(), lr=config.lr)
        x = torch.randn(config.batch_size, config.window_frames, INPUT_DIM, generator=torch.Generator().manual_seed(0))
        x, style = x.to(device), torch.zeros(config.batch_size, dtype=torch.long, device=device)

        def step() -> None:
            loss = F.cross_entropy(net(x)[0], style)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()

        row.rate = steps_per_second(step, args.steps, device)
        row.difference = classifier_difference(net, StyleClassifier(config, len(STYLES)), x[:2])

    return measured(Row("style classifier", preset), device, work)


def classifier_difference(net: torch.nn.Module, cpu_net: torch.nn.Module, x: torch.Tensor) -> float:
    """Largest logit difference of ``net`` on its device to ``cpu_net`` (same weights) on the CPU."""
    cpu_net.load_state_dict(net.state_dict())
    net.eval()
    cpu_net.eval()
    with torch.no_grad():
        a, b = net(x), cpu_net(x.cpu())
    return largest_difference(a[0] if isinstance(a, tuple) else a, b[0] if isinstance(b, tuple) else b)


def method_row(name: str, args: argparse.Namespace, device: torch.device, song: Song, dance: PoseSequence,
               stgcn_run: Path) -> Row:
    preset = "small" if args.tiny else "paper"

    def work(row: Row) -> None:
        config = make_config(name, preset, TINY_BATCH if args.tiny else None)
        if "stgcn_run" in {f.name for f in dataclasses.fields(config)}:
            config = dataclasses.replace(config, stgcn_run=str(stgcn_run))
        torch.manual_seed(0)
        method = build_method(name, config).to(device)
        method._optimizers = method.configure_optimizers()  # as stage1_pose.train.PoseTrainer does
        batch = stage1_batch(method.feature_kind, config.batch_size, config.window_frames, dance, song.beats)
        on_device = batch.to(device)
        method.train()
        row.rate = steps_per_second(lambda: method.training_step(on_device, 0), args.steps, device)
        cpu = build_method(name, config)
        cpu.load_state_dict(method.state_dict())
        method.eval()
        cpu.eval()
        frames = min(config.window_frames, 4 * int(POSE_FPS))
        with torch.no_grad():
            a = method.generate(on_device.features[:1, :frames], on_device.beats[:1, :frames],
                                generator=torch.Generator().manual_seed(0))
            b = cpu.generate(batch.features[:1, :frames], batch.beats[:1, :frames],
                             generator=torch.Generator().manual_seed(0))
        row.difference = largest_difference(a, b)

    return measured(Row(name, preset), device, work)


# --- stage 2 ------------------------------------------------------------------------------------------------------
def appearance_row(preset: str, args: argparse.Namespace, device: torch.device, target: tuple[Path, Path],
                   run: Path, vgg_weights: Path | None) -> Row:
    """``args.steps`` updates of the appearance model at ``preset`` on the synthetic person; the run is saved
    (trained that many steps) for the dance row."""
    video, poses = target

    def work(row: Row) -> None:
        trainer = video_trainer(video, run, preset, TrainOptions(epochs=1, val_frames=2), poses=poses,
                                vgg_weights=vgg_weights, device=str(device),
                                overrides=TINY_PIX2PIXHD[preset] if args.tiny else None)
        row.precision = precision_name(trainer.precision)
        batch = [torch.stack(xs) for xs in zip(*(trainer.train_set[i] for i in range(trainer.config.batch_size)))]
        row.rate = steps_per_second(lambda: trainer.train_step(batch), args.steps, device)
        trainer.step = args.steps  # the run says it trained: an untrained prior model renders the prior alone
        trainer.checkpoint(validate=False)
        row.difference = appearance_difference(trainer, batch[0][:1])

    return measured(Row(f"appearance model {preset}", preset), device, work)


def appearance_difference(trainer: VideoTrainer, label: torch.Tensor) -> float:
    """A generated frame under the trainer's autocast on its device against the float32 CPU forward."""
    model = trainer.model.eval()
    cpu = Pix2PixHD(trainer.config)
    cpu.load_state_dict(model.state_dict())
    with torch.no_grad():
        with torch.autocast(trainer.device.type, dtype=trainer.precision,
                            enabled=trainer.precision != torch.float32):
            a = model.generate(label.to(trainer.device))
        b = cpu.eval().generate(label)
    return largest_difference(a, b)


def dance_row(args: argparse.Namespace, device: torch.device, song: Path, run: Path, out: Path) -> Row:
    def work(row: Row) -> None:
        start = time.perf_counter()
        result = dancesynth.dance(song, out=out, video_model=run, device=str(device))
        row.rate = len(result.poses) / (time.perf_counter() - start)
        fast = load_appearance_model(run, str(device))
        reference = load_appearance_model(run, "cpu", optimize=False, precision="fp32")
        row.precision = precision_name(resolve_precision("auto", device))
        config = fast.config
        x = torch.rand(1, generator_channels(config), config.height, config.width,
                       generator=torch.Generator().manual_seed(0)) * 2 - 1
        with torch.inference_mode():
            row.difference = largest_difference(fast.generator(x.to(device)), reference.generator(x))

    return measured(Row("dance (256-px model)", "medium", unit="frames/s"), device, work)


# --- the check ----------------------------------------------------------------------------------------------------
def target_video(folder: Path, dance: PoseSequence, tiny: bool) -> tuple[Path, Path]:
    """The synthetic person dancing ``dance`` (15 fps): (video, poses file)."""
    seq = dance
    if tiny:
        seq = PoseSequence(seq.keypoints * (0.25, 0.25, 1), seq.fps, seq.width // 4, seq.height // 4)
    video, poses = folder / "person.mp4", folder / "person.npz"
    write_person_video(seq, video, appearance_preset("red_tee"))
    seq.save(poses)
    return video, poses


def random_vgg_weights(path: Path) -> Path:
    """A VGG19 ``features`` state dict of random weights: pix2pixHD's VGG loss at its real cost."""
    from torchvision.models.vgg import cfgs, make_layers

    torch.save(make_layers(cfgs["E"]).state_dict(), path)
    return path


def run_check(args: argparse.Namespace, device: torch.device, folder: Path) -> list[Row]:
    song, dance = song_and_dance(SONG_SECONDS[args.tiny])
    song_file = folder / "song.wav"
    soundfile.write(song_file, song.samples, song.sample_rate)
    rows = [stgcn_row(args, device, dance, folder / "stgcn")]
    rows += [method_row(name, args, device, song, dance, folder / "stgcn") for name in method_names()]
    rows.append(style_classifier_row(args, device))
    target = target_video(folder, dance, args.tiny)
    vgg = args.vgg_weights or (None if args.tiny else random_vgg_weights(folder / "vgg19.pth"))
    rows.append(appearance_row("paper", args, device, target, folder / "paper", vgg))
    rows.append(appearance_row("medium", args, device, target, folder / "medium", None))
    rows.append(dance_row(args, device, song_file, folder / "medium", folder / "dance.mp4"))
    return rows


def table(rows: list[Row], device: torch.device, steps: int) -> str:
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else "CPU"
    lines = [f"{name}, torch {torch.__version__}, {steps} steps per trainer", "",
             "| trainer | preset | precision | speed | peak GPU MiB | max abs GPU - CPU forward |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        if r.error:
            lines.append(f"| {r.name} | {r.preset} | {r.precision} | failed: {r.error} | | |")
            continue
        peak = "-" if r.peak_mib is None else f"{r.peak_mib:.0f}"
        lines.append(f"| {r.name} | {r.preset} | {r.precision} | {r.rate:.2f} {r.unit} | {peak} | "
                     f"{r.difference:.2e} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", choices=("cuda", "cpu"), default="cuda")
    parser.add_argument("--steps", type=int, default=20, help="update steps per trainer (at least 2)")
    parser.add_argument("--tiny", action="store_true", help="toy sizes: the CPU presets, batches of two")
    parser.add_argument("--vgg-weights", type=Path, help="torchvision vgg19 weights for the paper VGG loss")
    parser.add_argument("--out", type=Path, help="keep the runs and the dance here (default: a temporary folder)")
    args = parser.parse_args(argv)
    if args.steps < 2:
        parser.error("--steps must be at least 2 (the first step is not timed)")
    if args.device == "cuda" and not torch.cuda.is_available():
        print("gpu_check: no CUDA GPU here; nothing to check (run it on a machine with one).")
        return 0
    device = torch.device(args.device)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        rows = run_check(args, device, folder)
    print(table(rows, device, args.steps))
    return 1 if any(r.error for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
