"""Rendering a trained appearance model: pose sequence -> frames of the target person, streamed.

:func:`render_video` is the one frame pipeline of `dancesynth render` and `dancesynth dance`: poses from anywhere
are resampled to the target video's frame rate, given the target's bone lengths (:mod:`stage2_video.retarget`)
and normalised onto its body (:mod:`stage2_video.normalize`, with the target statistics stored in the model's JSON)
(:func:`onto_target`), then framed like the training frames, drawn as label maps and fed through the generator one
frame at a time (each frame conditions the next), so memory stays flat for any length; each frame is composited
into the target's scene (:mod:`stage2_video.composite`) unless the model's crop is asked for, and streamed to the
encoder. A model conditioned on the warped prior (:mod:`stage2_video.prior`) also warps the person's own
pixels from its frame bank onto each pose at ``prior_scale`` times its resolution; the network's correction (added
to the prior, or for models saved before 2026-12-05 RGB and a mask painted over it) is upsampled onto that, so
frames come out at the prior's size. Before its first training step such a model renders the warped prior alone.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import math
import os
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from dancesynth.core.checkpoint import POINTER, load_checkpoint, run_file_contents
from dancesynth.core.concurrency import read_ahead
from dancesynth.core.config import config_from_dict
from dancesynth.core.device import resolve_device, resolve_precision
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import atomic_path
from dancesynth.core.media import VideoWriter
from dancesynth.core.progress import track
from dancesynth.core.skeleton import BODY25_LIMBS, PoseSequence, resample
from stage2_video.composite import Compositor, load_plate, output_size, scene_compositor
from stage2_video.framing import Framing, VideoFraming, condition, framing_from_dict, label_map
from stage2_video.masks import masks_file
from stage2_video.models.pix2pixhd import (
    IMAGE_CHANNELS,
    Pix2PixHD,
    Pix2PixHDConfig,
    blend,
    blend_base,
    carry_correction,
    generator_channels,
    repair,
)
from stage2_video.normalize import BodyStats, fit_normalization
from stage2_video.prior import FrameBank, PriorRenderer, scaled_framing
from stage2_video.retarget import retarget_onto
from stage2_video.train import KIND
from stage2_video.training_data import (
    EXCLUDE_SECONDS,
    POSES_FILE,
    frame_bank,
    frames_file,
    prior_images,
    rendered_checkpoint,
    split_ranges,
    to_image,
    to_tensor,
)
from stage2_video.winograd import winograd_generator

if TYPE_CHECKING:
    import openvino

# A residual model's correction counts as the person where it changes a channel by this much ([-1, 1] scale: 13
# grey levels); the scene shows through fainter changes (noise of the correction over the background).
VISIBLE_CHANGE = 0.1


class _ChannelsLast(nn.Module):
    """Runs ``inner`` on a channels-last copy of its input (oneDNN's preferred layout for convolutions)."""

    def __init__(self, inner: nn.Module) -> None:
        super().__init__()
        self.inner = inner

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.inner(x.contiguous(memory_format=torch.channels_last))


class _Autocast(nn.Module):
    """Runs ``inner`` under autocast to ``dtype`` (bfloat16 or float16) and returns float32."""

    def __init__(self, inner: nn.Module, dtype: torch.dtype) -> None:
        super().__init__()
        self.inner, self.dtype = inner, dtype

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        with torch.autocast(x.device.type, dtype=self.dtype):
            return self.inner(x).float()


class OpenVINOGenerator:
    """The generator compiled by OpenVINO's CPU plugin for one input size, computing in ``precision``.

    float32: the residual blocks are first rewritten with Winograd convolutions (:mod:`stage2_video.winograd`, a
    quarter of the multiplies) and the output equals the plain forward up to float rounding
    (``benchmarks/bench_render.py``). bfloat16 (OpenVINO's ``INFERENCE_PRECISION_HINT``, for CPUs with AMX or
    AVX-512-BF16): direct convolutions, which were faster in bf16 (58.6 vs 38.4 frames/s at 256 px on a Xeon with
    AMX) and far closer to float32 than Winograd's transforms rounded to bf16 (``benchmarks/bench_precision.py``);
    ``winograd`` overrides that choice. Either way OpenVINO fuses the other convolutions with their instance norm
    and activation and keeps activations in blocked layouts between layers, which PyTorch's eager and
    TorchScript paths do not. ``cache``: a run folder to keep the converted network in (:data:`CONVERTED_DIR`), read
    back instead of converted again when nothing it depends on changed.
    """

    def __init__(self, generator: nn.Module, in_channels: int, width: int, height: int,
                 precision: torch.dtype = torch.float32, winograd: bool | None = None,
                 cache: Path | None = None) -> None:
        import openvino

        shape = (1, in_channels, height, width)
        use_winograd = precision == torch.float32 if winograd is None else winograd
        if cache is None:
            model = _convert(generator, shape, use_winograd)
        else:
            key = _converted_key(generator, shape, use_winograd)
            model = _read_converted(cache, key)
            if model is None:
                model = _convert(generator, shape, use_winograd)
                _write_converted(cache, key, model)
        compiled = openvino.Core().compile_model(model, "CPU", {
            "INFERENCE_PRECISION_HINT": "bf16" if precision == torch.bfloat16 else "f32", "PERFORMANCE_HINT": "LATENCY",
            "INFERENCE_NUM_THREADS": torch.get_num_threads()})
        self._request = compiled.create_infer_request()

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        """``[1, C, H, W]`` float32 CPU tensor -> ``[1, 3, H, W]`` frame in [-1, 1]."""
        # The result buffer belongs to the request and is overwritten by the next call.
        return torch.from_numpy(self._request.infer([x.numpy()])[0].copy())


# The converted network of a run's generator, kept in the run folder: converting takes seconds, reading it back a
# fraction of one. Its key names the weights, the input shape, the Winograd rewrite, OpenVINO's and PyTorch's
# versions and the code that builds the network, so anything that would convert differently converts again.
CONVERTED_DIR = "openvino"
_CONVERTED_XML = "generator.xml"
_CONVERTED_KEY = "key.txt"


def _convert(generator: nn.Module, shape: tuple[int, int, int, int], winograd: bool) -> openvino.Model:
    """``generator`` traced for ``[1, C, H, W]`` inputs of ``shape`` (its residual blocks first rewritten as Winograd
    convolutions with ``winograd``) and converted to an OpenVINO model."""
    import openvino

    example = torch.zeros(shape)
    with torch.no_grad(), warnings.catch_warnings():
        # The tracer warns about instance norm's shape checks, fixed for a fixed input size.
        warnings.simplefilter("ignore")
        # Traced here without autograd or the tracer's re-run check: left to the converter, tracing held about
        # 400 MB more at its peak for the small preset.
        if winograd:
            generator = winograd_generator(generator, shape[1], shape[3], shape[2])
        traced = torch.jit.trace(generator, example, check_trace=False)
        return openvino.convert_model(traced, example_input=example, input=[shape])


def _converted_key(generator: nn.Module, shape: tuple[int, ...], winograd: bool) -> str:
    import inspect

    import openvino

    from stage2_video import winograd as winograd_module

    digest = hashlib.sha256(json.dumps([list(shape), winograd, openvino.__version__, torch.__version__]).encode())
    for module in (inspect.getmodule(type(generator)), winograd_module):
        digest.update(Path(inspect.getfile(module)).read_bytes())
    for name, tensor in generator.state_dict().items():
        digest.update(name.encode())
        digest.update(tensor.detach().cpu().contiguous().view(torch.uint8).numpy())
    return digest.hexdigest()


def _read_converted(run_dir: Path, key: str) -> openvino.Model | None:
    """The network converted for ``key`` from ``RUN_DIR/openvino``, or None when it is missing, stale or unreadable."""
    import openvino

    folder = run_dir / CONVERTED_DIR
    try:
        if (folder / _CONVERTED_KEY).read_text() != key:
            return None
        return openvino.Core().read_model(folder / _CONVERTED_XML)
    except (OSError, RuntimeError, UnicodeDecodeError):
        return None


def _write_converted(run_dir: Path, key: str, model: openvino.Model) -> None:
    """Keep the converted ``model`` in ``RUN_DIR/openvino`` under ``key``; a folder that cannot be written (read-only,
    full) only costs the next render the conversion."""
    import openvino

    # OpenVINO reports a failed write as a RuntimeError, atomic_path an OSError as a DancesynthError.
    with contextlib.suppress(DancesynthError, RuntimeError):
        with atomic_path(run_dir / CONVERTED_DIR, folder=True) as tmp:
            tmp.mkdir()
            openvino.save_model(model, tmp / _CONVERTED_XML, compress_to_fp16=False)
            (tmp / _CONVERTED_KEY).write_text(key)


def optimize_generator(generator: nn.Module, in_channels: int, width: int, height: int, device: torch.device,
                       precision: torch.dtype = torch.float32,
                       cache: Path | None = None) -> Callable[[torch.Tensor], torch.Tensor]:
    """An inference-only copy of ``generator`` for ``[1, in_channels, height, width]`` inputs, computing in
    ``precision`` (float32 input and output).

    On CPU the network compiled by OpenVINO (:class:`OpenVINOGenerator`); on a GPU a channels-last copy traced
    (under autocast unless ``precision`` is float32) and frozen by TorchScript. In float32 the output equals the
    plain forward up to rounding (``benchmarks/bench_render.py`` measures the difference and the speed-up).
    ``cache``: the model's run folder, where the CPU's converted network is kept for the next render
    (:data:`CONVERTED_DIR`).
    """
    if device.type == "cpu":
        return OpenVINOGenerator(generator, in_channels, width, height, precision, cache=cache)
    wrapped = _ChannelsLast(copy.deepcopy(generator).eval().to(device, memory_format=torch.channels_last))
    if precision != torch.float32:
        wrapped = _Autocast(wrapped, precision)
    example = torch.zeros(1, in_channels, height, width, device=device)
    with torch.no_grad(), warnings.catch_warnings():
        # The tracer flags instance norm's shape checks (fixed for a fixed input size) and TorchScript is
        # deprecated in favour of torch.compile.
        warnings.simplefilter("ignore")
        return torch.jit.optimize_for_inference(torch.jit.trace(wrapped, example))


@dataclass
class AppearanceModel:
    """A trained generator with what rendering needs from its run folder."""

    # None: a model conditioned on the warped prior that has not trained yet (it renders the prior alone)
    generator: Callable[[torch.Tensor], torch.Tensor] | None
    config: Pix2PixHDConfig
    framing: VideoFraming
    target_stats: BodyStats | None
    fps: float
    device: torch.device
    canvas: tuple[int, int]  # (width, height) in pixels of the target video, upright: what the scene output has
    # [B] the target's median bone lengths (pixels of its canvas) for retargeting; None for runs saved before them
    bone_lengths: np.ndarray | None = None
    # [H, W, 3] uint8 background plate at the canvas size, for models conditioned on it (config.background)
    plate: np.ndarray | None = None
    # the target's frame bank, for models conditioned on the warped prior (config.prior)
    bank: FrameBank | None = None
    # the run folder it was loaded from (its plate and poses size the scene output); None for one built in memory
    run_dir: Path | None = None

    @property
    def scale(self) -> int:
        """Rendered frames are this many times the model's resolution (the warped prior's scale)."""
        return self.config.prior_scale if self.config.prior else 1

    def output_framing(self, framing: Framing) -> Framing:
        """The framing rendered frames have for a frame whose label map is drawn in ``framing``."""
        return scaled_framing(framing, self.scale)

    @torch.inference_mode()
    def step(self, cond: np.ndarray, previous: torch.Tensor | None) -> torch.Tensor:
        """``[H, W, C]`` uint8 condition (:func:`stage2_video.framing.condition`) + previous output ->
        ``[1, 3, H, W]`` frame in [-1, 1] (for a model conditioned on the warped prior, its raw output: ``[1, 4, H,
        W]`` RGB and mask, see :func:`stage2_video.models.pix2pixhd.blend`, or with ``residual`` the ``[1, 3, H,
        W]`` correction, see :func:`stage2_video.models.pix2pixhd.repair`)."""
        x = to_tensor(cond)[None].to(self.device)
        if self.config.temporal:
            x = torch.cat([x, x.new_zeros(1, IMAGE_CHANNELS, *x.shape[2:]) if previous is None else previous], dim=1)
        return self.generator(x)

    @torch.inference_mode()
    def step_with_prior(self, cond: np.ndarray, prior: np.ndarray,
                        previous: torch.Tensor | None) -> tuple[torch.Tensor, np.ndarray, np.ndarray]:
        """One frame of a model conditioned on the warped prior.

        Args:
            cond: ``[h, w, C]`` uint8 condition at the model's size (its last four channels the prior).
            prior: ``[scale h, scale w, 4]`` uint8 warped prior over the plate and its alpha at the output size.
            previous: the previous frame at the model's size (``[1, 3, h, w]``), or None.

        Returns:
            ``[1, 3, h, w]`` frame at the model's size (the next step's ``previous``), the ``[scale h, scale w, 3]``
            uint8 output frame and its ``[scale h, scale w]`` float32 coverage in [0, 1] (where the person may be:
            the warp's alpha, or the network's mask where larger).
        """
        high = torch.from_numpy(np.ascontiguousarray(prior)).to(self.device).permute(2, 0, 1)[None].float()
        base_high, alpha = high[:, :IMAGE_CHANNELS].div(127.5).sub(1.0), high[:, IMAGE_CHANNELS:].div(255.0)
        base_low = blend_base(to_tensor(cond)[None].to(self.device), True)
        if self.generator is None:
            return base_low, to_image(base_high[0]), alpha[0, 0].cpu().numpy()
        raw = self.step(cond, previous).to(self.device)
        if self.config.repairs:
            low = repair(raw, base_low)
            frame_high = carry_correction(low, base_low, base_high)
            # The person reaches wherever the correction changed the frame visibly, faint changes faded out.
            mask = (frame_high - base_high).abs().amax(1, keepdim=True).div(VISIBLE_CHANGE).clamp(max=1.0)
        else:
            low, _ = blend(raw, base_low)
            raw_high = F.interpolate(raw, size=prior.shape[:2], mode="bilinear", align_corners=False)
            frame_high, mask = blend(raw_high, base_high)
        coverage = torch.maximum(alpha, mask)
        return low, to_image(frame_high[0]), coverage[0, 0].cpu().numpy()


def _bank(run_dir: Path, config: Pix2PixHDConfig, framing: VideoFraming) -> FrameBank:
    """The frame bank of a run conditioned on the warped prior, from its cached frames, masks and poses."""
    bank_framing = scaled_framing(framing, config.prior_scale)
    paths = [run_dir / name for name in (frames_file(bank_framing), masks_file(bank_framing), POSES_FILE)]
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        raise DancesynthError(f"{run_dir} lacks {', '.join(missing)}, which the model's frame bank is made of; "
                              "train it again with `dancesynth train-video --resume` to rebuild them.")
    poses = PoseSequence.load(paths[2])
    frames, masks = np.load(paths[0], mmap_mode="r"), np.load(paths[1], mmap_mode="r")
    if len(frames) != len(poses) or len(masks) != len(poses):
        raise ValueError(f"the frame bank holds {len(frames)} frames and {len(masks)} masks for {len(poses)} poses")
    return frame_bank(frames, masks, poses, bank_framing, split_ranges(len(poses), config.val_fraction)[0],
                      config.prior_candidates)


def load_appearance_model(run_dir: str | os.PathLike, device: str = "auto", optimize: bool = True,
                          precision: str = "auto") -> AppearanceModel:
    """Load ``RUN_DIR/latest`` (kind "stage2") with the weights that scored best on its selection frames (the
    latest where it has none; the warped prior alone where the best is step 0); ``optimize`` compiles the generator
    for fast rendering; ``precision`` (``auto``, ``fp32``, ``bf16``, ``fp16`` on CUDA) is what it computes in
    (:func:`dancesynth.core.device.resolve_precision`)."""
    dev = resolve_device(device)
    dtype = resolve_precision(precision, dev)
    run_dir = Path(run_dir)
    state_dict, meta = load_checkpoint(run_dir, KIND, best=True)
    with run_file_contents(run_dir / POINTER):
        config = config_from_dict(Pix2PixHDConfig, meta["config"])
        model = Pix2PixHD(config)
        model.load_state_dict(state_dict)
        stats = BodyStats.from_dict(meta["target_stats"]) if meta.get("target_stats") else None
        framing, fps = framing_from_dict(meta["framing"]), float(meta["fps"])
        if not 0 < fps < math.inf:
            raise ValueError(f"fps {fps} is not a positive frame rate")
        canvas_width, canvas_height = (int(v) for v in meta["canvas"])
        if min(canvas_width, canvas_height) <= 0:
            raise ValueError(f"canvas {meta['canvas']} is not a frame size")
        lengths = np.asarray(meta["bone_lengths"], np.float64) if meta.get("bone_lengths") is not None else None
        if lengths is not None and lengths.shape != (len(BODY25_LIMBS),):
            raise ValueError(f"bone_lengths has shape {lengths.shape}, not [{len(BODY25_LIMBS)}]")
        untrained = int(rendered_checkpoint(meta).get("step", 1)) == 0
        bank = _bank(run_dir, config, framing) if config.prior else None
    # A prior model's network gives RGB and mask, painted over the prior at the output size (step_with_prior).
    generator = model.generator.inner if config.prior else model.generator
    generator = generator.eval().to(dev)
    if config.prior and untrained:
        generator = None
    elif optimize:
        generator = optimize_generator(generator, generator_channels(config), config.width, config.height, dev, dtype,
                                       run_dir)
    elif dtype != torch.float32:
        generator = _Autocast(generator, dtype)
    plate = load_plate(run_dir) if config.background else None
    return AppearanceModel(generator, config, framing, stats, fps, dev, (canvas_width, canvas_height),
                           bone_lengths=lengths, plate=plate, bank=bank, run_dir=run_dir)


def onto_target(model: AppearanceModel, poses: PoseSequence, normalize: bool = True) -> PoseSequence:
    """``poses`` (pixels of any canvas, any fps) as ``model`` renders them: resampled to the target video's fps
    (PCHIP, the timing kept in seconds), then given the target's bone lengths (runs saved before them: skipped) and
    moved onto the target's body by the Everybody Dance Now normalisation, in that order (see
    :mod:`stage2_video.retarget` for why). ``normalize`` False: poses already on the target's canvas, only resampled."""
    poses = resample(poses, model.fps)
    if not normalize:
        return poses
    if model.target_stats is None:
        raise DancesynthError("This model has no target body statistics (the target video never showed head and "
                              "ankles together); render poses on its canvas with `dancesynth render --no-normalize`.")
    if model.bone_lengths is not None:
        poses = retarget_onto(poses, model.bone_lengths)
    return fit_normalization(poses, model.target_stats).apply(poses)


def render_layers(model: AppearanceModel, poses: PoseSequence, framings: list[Framing] | None = None,
                  first_frame: int | None = None) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
    """Yield per pose (pixels of the target's canvas, :func:`onto_target`), in order, one ``[height, width, 3]``
    uint8 RGB frame (the model's resolution times ``model.scale``, framed by ``model.output_framing(framings[t])``)
    and, for models conditioned on the warped prior, its ``[height, width]`` float32 coverage in [0, 1] (else
    None). Frame t's label map is drawn in ``framings[t]`` (default: the model's framing of the poses,
    ``model.framing.frames``). ``first_frame``: the target video's frame the first pose was taken from, to render
    the model's own training frames as training warps them (never from bank frames within ``EXCLUDE_SECONDS``);
    None: from any bank frame."""
    previous = None
    renderer = None
    if model.bank is not None:
        window = None if first_frame is None else round(EXCLUDE_SECONDS * poses.fps)
        renderer = PriorRenderer(model.bank, exclude_frames=window)
    size = (model.config.width, model.config.height)
    pairs = zip(poses.keypoints, framings or model.framing.frames(poses))
    if renderer is None:
        for keypoints, framing in pairs:
            previous = model.step(condition(keypoints, framing, model.plate), previous)
            yield to_image(previous[0]), None
        return

    def conditions() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        for t, (keypoints, framing) in enumerate(pairs):
            frame_index = None if first_frame is None else first_frame + t
            high, low = prior_images(renderer, keypoints, model.output_framing(framing), model.plate, size,
                                     frame_index)
            yield condition(keypoints, framing, model.plate, low), high

    # The warp (mostly Python) runs up to two frames ahead in a thread while the network (native, GIL released)
    # runs here.
    for label, high in read_ahead(conditions()):
        previous, frame, coverage = model.step_with_prior(label, high, previous)
        yield frame, coverage


def render_frames(model: AppearanceModel, poses: PoseSequence,
                  framings: list[Framing] | None = None) -> Iterator[np.ndarray]:
    """The frames of :func:`render_layers` alone."""
    for frame, _ in render_layers(model, poses, framings):
        yield frame


def output_frames(model: AppearanceModel, poses: PoseSequence, compositor: Compositor | None,
                  labels: bool) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
    """Per pose (pixels of the target's canvas, :func:`onto_target`): the output frame, composited into the scene
    by ``compositor`` (``[height, width, 3]`` uint8 at its size), or the model's crop when it is None; and, when
    ``labels``, the skeleton drawn at the same size and place (else None)."""
    framings = model.framing.frames(poses)
    for keypoints, framing, (frame, coverage) in zip(poses.keypoints, framings,
                                                      render_layers(model, poses, framings)):
        framed = model.output_framing(framing)
        if compositor is not None:
            frame = compositor.frame(frame, keypoints, framed, coverage)
        label = None
        if labels:
            label = label_map(keypoints, framed) if compositor is None else compositor.skeleton(keypoints)
        yield frame, label


def check_output_options(crop: bool, height: int | None) -> None:
    """Refuse ``crop`` together with ``height`` (pixels), before any work."""
    if crop and height is not None:
        raise DancesynthError("--height sizes the whole-scene output and --crop writes the model's crop; "
                              "use one of them.")


@dataclass
class Rendered:
    """What :func:`render_video` produced."""

    poses: PoseSequence  # the poses rendered: at the target video's fps, on its canvas (pixels)
    written: list[Path]  # the video, then the skeleton preview and the side-by-side video where asked for
    seconds: float  # wall seconds of the frame loop (rendering, compositing, encoding every output)


def render_video(poses: PoseSequence, model: AppearanceModel, out: str | os.PathLike,
                 audio: np.ndarray | None = None, audio_sr: int | None = None, normalize: bool = True,
                 crop: bool = False, height: int | None = None, skeleton_preview: str | os.PathLike | None = None,
                 side_by_side: str | os.PathLike | None = None, progress: bool = True) -> Rendered:
    """The frame pipeline of `render` and `dance`: ``poses`` (pixels, any canvas and fps) -> the person of
    ``model`` dancing them in an mp4 at ``out``, at the target video's fps.

    The poses go :func:`onto_target` (resample, retarget, normalise; ``normalize`` False: poses already on the
    target's canvas, only resampled), through the generator and into the target's scene over its background plate
    at the target video's resolution, or ``height`` pixels high with the aspect kept; ``crop`` writes the model's
    crop instead (its resolution times ``model.scale``). ``skeleton_preview`` and ``side_by_side`` (skeleton |
    person) are further mp4s at the same height. ``audio`` (mono float32 at ``audio_sr`` Hz) is muxed into each,
    cut or padded to the video's duration. One generator pass feeds every output; each is written atomically.
    """
    check_output_options(crop, height)
    poses = onto_target(model, poses, normalize)
    if crop:
        compositor = None
        width, out_height = model.scale * model.config.width, model.scale * model.config.height
    else:
        if model.run_dir is None:
            raise ValueError("a model built in memory has no scene to composite into; render its crop")
        compositor = scene_compositor(model.run_dir, output_size(model.canvas, height))
        width, out_height = compositor.size
    outputs = [(Path(out), width)]
    if skeleton_preview is not None:
        outputs.append((Path(skeleton_preview), width))
    if side_by_side is not None:
        outputs.append((Path(side_by_side), 2 * width))
    with contextlib.ExitStack() as stack:
        writers = [stack.enter_context(VideoWriter(path, poses.fps, w, out_height, audio=audio, audio_sr=audio_sr))
                   for path, w in outputs]
        started = time.perf_counter()
        frames = read_ahead(output_frames(model, poses, compositor, len(writers) > 1))
        for frame, label in track(frames, total=len(poses), desc="rendering", unit="frame", disable=not progress):
            writers[0].write(frame)
            if skeleton_preview is not None:
                writers[1].write(label)
            if side_by_side is not None:
                writers[-1].write(np.concatenate([label, frame], axis=1))
    return Rendered(poses, [path for path, _ in outputs], time.perf_counter() - started)
