"""The public Python API: one function per `dancesynth` command, with the command's defaults.

>>> import dancesynth
>>> dancesynth.dance("song.mp3", target="me.mp4", out="me_dancing.mp4")

Paths may be ``str`` or ``os.PathLike``. Bad input raises :class:`dancesynth.core.errors.DancesynthError`
with a one-sentence message. Progress and messages go to :mod:`logging` (configure it, e.g.
``logging.basicConfig(level=logging.INFO)``, to see them). The heavy modules (torch, the models) are
imported when a function is first called, not when :mod:`dancesynth` is imported.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stage1_pose.beat_tracking.trackers import DEFAULT_BEAT_TRACKER

if TYPE_CHECKING:
    from apps.pipeline import DanceResult
    from dancesynth.core.skeleton import PoseSequence
    from stage2_video.extract import Extraction
    from stage2_video.render import Rendered

PathLike = str | os.PathLike


def dance(song: PathLike, *, out: PathLike, target: PathLike | None = None, video_model: PathLike | None = None,
          pose_model: PathLike | None = None, cache: PathLike | None = None, train_minutes: float | None = None,
          preset: str | None = None, method: str | None = None, seed: int = 0, start: float = 0.0,
          duration: float | None = None, height: int | None = None, crop: bool = False,
          skeleton_preview: PathLike | None = None, side_by_side: PathLike | None = None,
          beat_snap: bool = True, precision: str = "auto", device: str = "auto",
          beats: str = DEFAULT_BEAT_TRACKER) -> DanceResult:
    """Make ``out`` (mp4): the person of ``target`` (a video) or ``video_model`` dancing to ``song``, in their
    own scene at its resolution, with the song as its sound.

    Args:
        song: any audio FFmpeg reads (wav, mp3, ogg, m4a, flac, or a video's soundtrack).
        target: a video of the person; their appearance model is taken from ``cache`` (default
            ``~/.cache/dancesynth/appearance``) or trained now until it has trained ``train_minutes`` in all
            (default 30; a later call with more minutes continues it; 0 renders the person's own pixels warped
            onto the dance, untrained), at ``preset`` (one of :data:`stage2_video.presets.PRESETS`, or ``auto``,
            the default: ``medium`` on GPUs and AMX CPUs, ``small`` elsewhere). ``cache``, ``train_minutes`` and
            ``preset`` go with ``target`` only.
        video_model: instead of ``target``, a stage-2 run folder (:func:`train_video`).
        pose_model: a stage-1 run folder (:func:`train_pose`) or a folder of runs named by method; None = the
            pose model shipped with dancesynth.
        method: which run to use when ``pose_model`` holds several (default ``dance_revolution``).
        seed: another seed gives another dance.
        start, duration: the song segment in seconds (``duration`` None = to the end of the song).
        height: output height in pixels, aspect kept (default: the target video's).
        crop: write the model's crop around the person instead of the whole scene.
        skeleton_preview: also write the skeleton as an mp4 (same size).
        side_by_side: also write skeleton | generated person as an mp4.
        beat_snap: retime the dance so that its movement beats land on the song's beats (False: the pose
            model's own timing).
        beats: the beat tracker, ``combined``, ``learned`` or ``dsp`` (:data:`stage1_pose.beats.BEAT_TRACKERS`).
        precision: appearance-model arithmetic: ``auto`` (bf16 on CPUs with AMX/AVX-512-BF16 and GPUs),
            ``fp32`` or ``bf16``.
        device: ``auto`` (GPU when available), ``cpu`` or ``cuda``.

    Returns:
        the dance at the video's fps on the target's canvas (``.poses``), the files written (``.written``) and
        the appearance model used (``.video_model``).
    """
    arguments = dict(locals())  # exactly DanceRequest's fields (tests/apps/test_requests.py checks)
    from apps.pipeline import dance as make_dance
    from apps.requests import DanceRequest

    DanceRequest.check_arguments(arguments)
    return make_dance(DanceRequest(**arguments))


def generate(song: PathLike, *, model: PathLike | None = None, out: PathLike | None = None, seed: int = 0,
             preview: PathLike | None = None, beat_snap: bool = True, precision: str = "auto",
             device: str = "auto", beats: str = DEFAULT_BEAT_TRACKER) -> PoseSequence:
    """A dance for ``song`` (any length) from the stage-1 run folder ``model`` (None = the pose model shipped
    with dancesynth).

    Args:
        out: also save the dance there (.npz: keypoints ``[T, 25, 3]`` in pixels of the training canvas,
            confidence 1; fps, width, height; the song's ``beats`` and ``downbeats`` in seconds); ``T`` = song
            length in seconds x the model's fps.
        seed: another seed gives another dance (for stochastic methods).
        preview: also write a skeleton mp4 with the song as its sound.
        beat_snap: retime the dance so that its movement beats land on the song's beats (False: the model's
            own timing).
        beats: the beat tracker, ``combined``, ``learned`` or ``dsp`` (``dsp``'s downbeats: every fourth beat).
        precision: ``int8`` decodes about 3x faster on CPU; ``auto`` = int8 on CPU, fp32 on GPU.
        device: ``auto``, ``cpu`` or ``cuda``.
    """
    from apps.requests import GenerateRequest
    from dancesynth.core.draw import write_skeleton_video
    from dancesynth.core.fileio import atomic_path, check_outputs, check_video_names
    from dancesynth.core.media import SONG_SAMPLE_RATE, load_song
    from stage1_pose.beat_snap import DEFAULT_SNAP
    from stage1_pose.beats import song_beats
    from stage1_pose.generate import generate_dance, load_pose_model
    from stage1_pose.pretrained import DEFAULT_POSE_MODEL

    GenerateRequest.check_arguments(locals())
    check_video_names({"preview": preview})
    check_outputs({"pose file": out, "preview": preview}, {"song": song, "pose model": model})
    loaded = load_pose_model(DEFAULT_POSE_MODEL if model is None else model, device, precision)
    samples = load_song(song, SONG_SAMPLE_RATE)
    tracked = song_beats(samples, SONG_SAMPLE_RATE, beats)
    poses = generate_dance(loaded, samples, SONG_SAMPLE_RATE, seed=seed, snap=DEFAULT_SNAP if beat_snap else None,
                           beats=tracked)
    # Both outputs are renamed into place only once both are complete, so a failure leaves neither.
    with contextlib.ExitStack() as outputs:
        if out is not None:
            poses.save(outputs.enter_context(atomic_path(out)), beats=tracked.beats, downbeats=tracked.downbeats)
        if preview is not None:
            write_skeleton_video(poses, outputs.enter_context(atomic_path(preview)), audio=samples,
                                 audio_sr=SONG_SAMPLE_RATE)
    return poses


def render(poses: PoseSequence | PathLike, *, model: PathLike, out: PathLike, audio: PathLike | None = None,
           normalize: bool = True, height: int | None = None, crop: bool = False,
           skeleton_preview: PathLike | None = None, side_by_side: PathLike | None = None, optimize: bool = True,
           device: str = "auto", precision: str = "auto") -> Rendered:
    """Render ``poses`` (a PoseSequence or a .npz pose file) as the mp4 ``out`` of the person of the stage-2 run
    ``model``, through the frame pipeline :func:`dance` uses (:func:`stage2_video.render.render_video`).

    Args:
        audio: a song to mux (any FFmpeg format), cut or padded to the video's length.
        normalize: give the poses the target's bone lengths and move them onto the target's body (Everybody
            Dance Now); False for poses that are already on the target's canvas.
        height: output height in pixels, aspect kept (default: the target video's).
        crop: write the model's crop around the person instead of the whole scene.
        skeleton_preview: also write the skeleton as an mp4 (same size).
        side_by_side: also write skeleton | generated person as an mp4.
        optimize: the fast inference path (OpenVINO on CPU); False for plain PyTorch.
        device: ``auto``, ``cpu`` or ``cuda``.
        precision: ``auto`` (bf16 on CPUs with AMX/AVX-512-BF16 and on GPUs, fp16 on GPUs without bf16, else
            fp32), ``fp32``, ``bf16`` or ``fp16`` (CUDA).

    Returns:
        the poses rendered, resampled to the target video's fps and on its canvas (``.poses``), and the files
        written (``.written``, the video first).
    """
    from apps.requests import RenderRequest
    from dancesynth.core.fileio import check_outputs, check_video_names
    from dancesynth.core.media import AAC_RATE, decode_audio
    from dancesynth.core.skeleton import PoseSequence
    from stage2_video.render import check_output_options, load_appearance_model, render_video

    RenderRequest.check_arguments(locals())
    check_output_options(crop, height)
    videos = {"video": out, "skeleton preview": skeleton_preview, "side-by-side video": side_by_side}
    check_video_names(videos)
    check_outputs(videos, {"pose file": None if isinstance(poses, PoseSequence) else poses,
                           "appearance model": model, "audio": audio})
    if not isinstance(poses, PoseSequence):
        poses = PoseSequence.load(poses)
    appearance = load_appearance_model(model, device, optimize=optimize, precision=precision)
    # The soundtrack is decoded at the rate it is encoded at, so it is not resampled twice.
    samples = decode_audio(audio, AAC_RATE) if audio is not None else None
    return render_video(poses, appearance, out, audio=samples, audio_sr=AAC_RATE if audio is not None else None,
                        normalize=normalize, crop=crop, height=height, skeleton_preview=skeleton_preview,
                        side_by_side=side_by_side)


def extract_poses(video: PathLike, *, out: PathLike | None = None, preview: PathLike | None = None,
                  smoothing: str = "savgol", window_s: float | None = None, min_cutoff_hz: float | None = None,
                  beta: float | None = None, spike_window_s: float | None = None,
                  min_visibility: float | None = None, max_missing: float | None = None) -> Extraction:
    """One person's BODY_25 skeleton in every frame of ``video`` (BlazePose, on the CPU).

    Args:
        out: also save the poses there (.npz; keypoints ``[T, 25, 3]``: x, y in pixels, confidence).
        preview: also write an mp4 of the skeleton drawn over the video.
        smoothing: ``savgol`` (no lag), ``one-euro`` (causal) or ``none``.
        window_s: Savitzky-Golay window in seconds. min_cutoff_hz, beta: One-Euro settings.
        spike_window_s: joints that leap away and back within this many seconds are swapped back or dropped and
            filled in before the filter (:func:`stage2_video.smoothing.despike`); 0: off.
        min_visibility: BlazePose visibility below which a joint counts as absent.
        max_missing: fail when the person is missing in more than this fraction of the frames.
        Settings left None take :class:`stage2_video.extract.ExtractConfig`'s defaults.

    Returns:
        the poses, which frames had the person (``.found``) and what the tracker did (``.stats``).
    """
    from apps.requests import ExtractPosesRequest
    from dancesynth.core.errors import DancesynthError
    from dancesynth.core.fileio import check_outputs, check_video_names
    from stage2_video.extract import ExtractConfig, write_preview
    from stage2_video.extract import extract_poses as extract
    from stage2_video.smoothing import SmoothingConfig

    ExtractPosesRequest.check_arguments(locals())
    if out is not None and Path(out).suffix != ".npz":
        raise DancesynthError(f"{out} must end in .npz; choose another file name.")
    check_video_names({"preview": preview})
    for path in (out, preview):
        if path is not None and not Path(path).parent.is_dir():
            raise DancesynthError(f"The folder {Path(path).parent} does not exist; create it or choose another path.")
    check_outputs({"pose file": out, "preview": preview}, {"video": video})
    smoothing_settings = _given(window_s=window_s, min_cutoff_hz=min_cutoff_hz, beta=beta,
                                spike_window_s=spike_window_s)
    settings = _given(min_visibility=min_visibility, max_missing_fraction=max_missing)
    config = ExtractConfig(smoothing=SmoothingConfig(smoothing, **smoothing_settings), **settings)
    result = extract(video, config)
    if out is not None:
        result.poses.save(out)
    if preview is not None:
        write_preview(video, result.poses, preview)
    return result


def train_pose(method: str, *, data: PathLike, out: PathLike, preset: str = "small",
               overrides: dict[str, Any] | None = None, epochs: int | None = None, minutes: float | None = None,
               batch_size: int | None = None, window: int | None = None, resume: bool = False,
               checkpoint_every: int = 200, preview_every: int = 10, preview_gap: float = 2.0, seed: int = 0,
               workers: int = 0, device: str = "auto") -> dict[str, Any]:
    """Train the stage-1 ``method`` (see ``stage1_pose.registry.method_names()``) on the dataset folder ``data``.

    Args:
        out: the run folder (weights, metrics.csv, loss.png, previews/).
        preset: ``small`` (CPU, minutes) or ``paper`` (published settings); ``overrides`` replace fields of it.
        epochs: total epochs (default: the preset's); ``minutes``: wall-clock training time of the run in all
            (every call together), it stops earlier with a checkpoint.
        batch_size: global batch size in windows; ``window``: training window length in pose frames.
        resume: continue the run in ``out`` exactly (a larger ``epochs`` or ``minutes`` extends a finished one);
            Ctrl-C or SIGTERM saves a checkpoint, then raises :class:`KeyboardInterrupt`.
        checkpoint_every: optimizer steps between checkpoints.
        preview_every: epochs between preview videos (0 = none), at most one per ``preview_gap`` minutes.
        workers: data loader worker processes.
        seed: the seed of the initial weights, the data order and every random draw.
        device: ``auto`` (GPU when available), ``cpu`` or ``cuda``.

    Returns:
        the final checkpoint's metadata (method, epoch, epochs, step, config, ...).
    """
    from apps.requests import TrainPoseRequest
    from dancesynth.core.fileio import check_outputs
    from stage1_pose.train import TrainerConfig
    from stage1_pose.train import train as train_method

    TrainPoseRequest.check_arguments(locals())
    check_outputs({}, {"dataset": data}, folders={"run folder": out})
    options = TrainerConfig(batch_size=batch_size, window_frames=window, checkpoint_every=checkpoint_every,
                            preview_every=preview_every, preview_gap_minutes=preview_gap, seed=seed,
                            num_workers=workers)
    return train_method(method, data, out, preset=preset, epochs=epochs, resume=resume, device=device,
                        overrides=overrides, minutes=minutes, options=options)


def train_video(video: PathLike, *, out: PathLike, preset: str = "small", overrides: dict[str, Any] | None = None,
                minutes: float | None = None, epochs: int | None = None, resume: bool = False,
                poses: PathLike | None = None, vgg_weights: PathLike | None = None, checkpoint_every: int = 200,
                sample_every: int = 200, seed: int = 0, device: str = "auto",
                precision: str = "auto") -> dict[str, Any]:
    """Train the appearance model (pix2pixHD + temporal smoothing) of the person in ``video``.

    Args:
        out: the run folder (weights, validation.csv, samples/, losses.csv, losses.png).
        preset: one of :data:`stage2_video.presets.PRESETS` (``small``: CPU, 128 px; ``medium``: 256 px;
            ``paper``: 1024x512, local enhancer, GPU); ``overrides`` replace fields of it, e.g. ``{"ngf": 64}``.
        minutes: wall-clock training time of the run in all (every call together); ``epochs``: total epochs.
            One of them is required.
        resume: continue the run in ``out`` exactly; Ctrl-C or SIGTERM saves a checkpoint, then raises
            :class:`KeyboardInterrupt`.
        poses: a pose file of ``video`` to use instead of extracting poses.
        vgg_weights: local torchvision vgg19 weights (.pth/.safetensors) for the perceptual loss (off without).
        checkpoint_every, sample_every: steps between checkpoints and between sample grids.
        seed: the seed of the initial weights, the data order and every random draw.
        device: ``auto`` (GPU when available), ``cpu`` or ``cuda``.
        precision: what the forward passes compute in (weights stay float32): ``auto`` (bf16 on CPUs with
            AMX/AVX-512-BF16 and on GPUs, fp16 on GPUs without bf16, else fp32), ``fp32``, ``bf16`` or ``fp16``.

    Returns:
        the last checkpoint's metadata (epoch, step, validation SSIM/PSNR, ...).
    """
    from apps.requests import TrainVideoRequest
    from dancesynth.core.fileio import check_outputs
    from stage2_video.train import TrainOptions
    from stage2_video.train import train_video as train_appearance

    TrainVideoRequest.check_arguments(locals())
    check_outputs({}, {"target video": video, "pose file": poses, "VGG weights": vgg_weights},
                  folders={"run folder": out})
    options = TrainOptions(minutes=minutes, epochs=epochs, checkpoint_every=checkpoint_every,
                           sample_every=sample_every, seed=seed)
    return train_appearance(video, out, preset, options, resume=resume, poses=poses, vgg_weights=vgg_weights,
                            device=device, overrides=overrides, precision=precision)


def _given(**settings: Any) -> dict[str, Any]:
    """The settings that are not None (the others keep their config defaults)."""
    return {k: v for k, v in settings.items() if v is not None}
