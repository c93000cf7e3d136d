"""One definition per user action: a frozen dataclass per action holding each field's name, type, default and
help, and how the command line, the Python API and the web page spell and check it.

Each field of a request is an :class:`Option` (in the dataclass field's metadata). From the request type come

- the command's arguments (:meth:`Request.add_arguments`, argparse with the ``type=`` checkers of
  :mod:`apps.arguments`) and the request a parsed command line makes (:meth:`Request.from_namespace`),
- the API function's keyword arguments (:meth:`Request.api_kwargs`; ``tests/apps/test_requests.py`` checks that
  each function of :mod:`dancesynth.api` has exactly these parameters, defaults and documented arguments),
- the "equivalent command" of a request (:meth:`Request.to_command`: only the fields that differ from their
  default), which the command's own parser reads back into the same request,
- the web page's job fields (:class:`Page`: their key in a job request, the words a sentence names them by and the
  range the server accepts; :meth:`Request.from_form` reads and checks them, :meth:`Request.to_form` writes them).

The module imports nothing heavy, so every command's ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, ClassVar, Self

from apps.arguments import (
    PATH_CHECKS,
    existing_file,
    fraction,
    non_negative_float,
    non_negative_int,
    output_file,
    output_folder,
    output_video,
    positive_float,
    positive_int,
    video_height,
)
from dancesynth.core.errors import DancesynthError
from stage1_pose.beat_tracking.trackers import BEAT_TRACKERS, DEFAULT_BEAT_TRACKER
from stage2_video.presets import describe_presets, preset_names

PathLike = str | os.PathLike


OPTION = "option"  # the key of a request field's metadata that holds its Option
# A number as JSON or the page's inputs write it: no underscores, hex or words (Python's float reads "1_0" as 10).
NUMBER = re.compile(r"\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*")
MINUTES_A_DAY, SECONDS_A_DAY = 24 * 60.0, 24 * 3600.0


def shown(value: object) -> str:
    """``repr(value)``, cut to a length a sentence can hold."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:37]}..."


@dataclass(frozen=True)
class Page:
    """How the web page sends a number field: its ``key`` in a job request, the words ``what`` a sentence names it
    by, and the range ``[low, high]`` the server accepts (in the field's unit)."""

    key: str
    what: str
    low: float
    high: float

    def read(self, form: Mapping[str, Any], default: Any, integer: bool) -> Any:
        """The number ``form[key]`` (a JSON number, or a decimal in a string as the page's inputs send it; absent,
        null or "": the default), checked to lie in the range (and to be whole when ``integer``); a
        :class:`DancesynthError` sentence when it does not."""
        value = form.get(self.key)
        if value is None or value == "":
            return default
        number = (float(value) if isinstance(value, (int, float)) and not isinstance(value, bool)
                  else float(value) if isinstance(value, str) and NUMBER.fullmatch(value) else None)
        if number is None or (integer and not number.is_integer()):
            raise DancesynthError(f"The {self.what} must be a {'whole ' if integer else ''}number, got {shown(value)}.")
        if not self.low <= number <= self.high:
            raise DancesynthError(f"The {self.what} must be between {self.low:g} and {self.high:g}, "
                                  f"got {shown(value)}.")
        return int(number) if integer else number


@dataclass(frozen=True)
class Option:
    """A request field's command-line spelling and check.

    The flag is ``--field-name`` (``--no-field-name`` for a field that is True by default, which the flag turns
    off; a field False by default is a switch), or ``flag``; ``positional`` fields are the command's positional
    arguments. A field without a default is required; the fields sharing a ``one_of`` name are a required
    mutually exclusive group (exactly one is given). A tuple default makes a repeatable option. ``const``: the
    value the flag alone means (its value is optional). ``cli_only``: the command uses the field itself, the API
    function has no such parameter. ``page``: how the web page sends it (None: it does not).
    """

    help: str
    # dataclasses.MISSING: required. A factory, as a plain ``= MISSING`` would make ``default`` a required argument.
    default: Any = dataclasses.field(default_factory=lambda: dataclasses.MISSING)
    type: Callable[[str], Any] | None = None
    choices: tuple[str, ...] | Callable[[], tuple[str, ...]] | None = None
    metavar: str | None = None
    flag: str | None = None
    positional: bool = False
    one_of: str | None = None
    const: str | None = None
    cli_only: bool = False
    page: Page | None = None

    def field(self, **changes: Any) -> Any:
        """A dataclass field holding this option with ``changes`` (e.g. another ``help``)."""
        option = replace(self, **changes)
        return dataclasses.field(default=option.default, metadata={OPTION: option})

    def spelling(self, name: str) -> str:
        """How the command line names the field ``name``: its flag, or its name when it is positional."""
        if self.positional:
            return name
        if self.flag is not None:
            return self.flag
        return ("--no-" if self.default is True else "--") + name.replace("_", "-")

    def add_to(self, parser: argparse._ActionsContainer, name: str) -> None:
        """Add the field ``name`` to ``parser`` (or to a group of it)."""
        choices = self.choices() if callable(self.choices) else self.choices
        if self.positional:
            parser.add_argument(name, type=self.type, choices=choices, metavar=self.metavar, help=self.help)
            return
        spec: dict[str, Any] = {"dest": name, "help": self.help}
        if isinstance(self.default, bool):
            spec["action"] = "store_false" if self.default else "store_true"
        else:
            spec.update(type=self.type, choices=choices, metavar=self.metavar)
            if self.default is dataclasses.MISSING:
                spec["required"] = True
            elif isinstance(self.default, tuple):
                spec.update(action="append", default=list(self.default))
            else:
                spec["default"] = self.default
            if self.const is not None:
                spec.update(nargs="?", const=self.const)
        parser.add_argument(self.spelling(name), **spec)


def _text(value: Any) -> str:
    """``value`` as a command line writes it: a float as short as reads back the same."""
    if isinstance(value, float):
        short = f"{value:g}"
        return short if float(short) == value else repr(value)
    return os.fspath(value) if isinstance(value, os.PathLike) else str(value)


class Request:
    """What a user asks one action to do; subclasses are frozen keyword-only dataclasses of :class:`Option` fields,
    named by their command (``COMMAND``)."""

    COMMAND: ClassVar[str]

    @classmethod
    def options(cls) -> dict[str, Option]:
        """Every field's option, by field name, in the order of the command's --help."""
        return {f.name: f.metadata[OPTION] for f in dataclasses.fields(cls)}

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """Add every field to the command's ``parser``."""
        groups: dict[str, argparse._MutuallyExclusiveGroup] = {}
        for name, option in cls.options().items():
            target = parser
            if option.one_of is not None:
                if option.one_of not in groups:
                    groups[option.one_of] = parser.add_mutually_exclusive_group(required=True)
                target = groups[option.one_of]
            option.add_to(target, name)

    @classmethod
    def from_namespace(cls, args: argparse.Namespace) -> Self:
        """The request a command line parsed by :meth:`add_arguments`'s parser makes."""
        values = {name: getattr(args, name) for name in cls.options()}
        return cls(**{name: tuple(v) if isinstance(v, list) else v for name, v in values.items()})

    def to_command(self) -> list[str]:
        """The command line making this request (``dancesynth``, the command, then its arguments), fields at their
        default left out; ``shlex.join`` makes it one line to show."""
        positional, flags = [], []
        for name, option in self.options().items():
            value, flag = getattr(self, name), option.spelling(name)
            if option.positional:
                positional.append(_text(value))
            elif value == option.default:
                continue
            elif isinstance(value, bool):
                flags.append(flag)
            elif isinstance(value, tuple):
                flags += [word for item in value for word in (flag, _text(item))]
            else:
                flags += [flag, _text(value)]
        return ["dancesynth", self.COMMAND, *positional, *flags]

    @classmethod
    def check_arguments(cls, arguments: Mapping[str, Any]) -> None:
        """Check an API call's ``arguments`` as the command line checks its own: each field by its option's
        ``type`` (given the value as a command line writes it) and choices. Paths are left to the API, which checks
        them itself (:func:`dancesynth.core.fileio.check_outputs`); None, a switch's bool, values no command line
        holds (a PoseSequence, a dict) and arguments that are no field pass. The first bad one raises a
        one-sentence :class:`DancesynthError` naming it."""
        options = cls.options()
        for name, value in arguments.items():
            option = options.get(name)
            if (option is None or value is None or isinstance(option.default, bool) or option.type in PATH_CHECKS
                    or not isinstance(value, str | os.PathLike | int | float | tuple)):
                continue
            choices = option.choices() if callable(option.choices) else option.choices
            for item in value if isinstance(value, tuple) else (value,):
                try:
                    if option.type is not None:
                        option.type(_text(item))
                except argparse.ArgumentTypeError as error:
                    raise DancesynthError(f"{name}: {error}.") from None
                if choices is not None and item not in choices:
                    raise DancesynthError(f"{name}: {shown(item)} is not one of {', '.join(choices)}.")

    def api_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of the API function making this request (every field but the command's own)."""
        return {name: getattr(self, name) for name, option in self.options().items() if not option.cli_only}

    @classmethod
    def from_form(cls, form: Mapping[str, Any], **values: Any) -> Self:
        """The request of a web page's job request ``form``: each field the page sends (its option's :class:`Page`)
        read from it and checked (a one-sentence :class:`DancesynthError`), the other fields from ``values`` (what
        the server resolved: paths of uploads, its device); ``values`` win over the form."""
        # A field whose default is an int takes whole numbers only.
        read = {f.name: f.metadata[OPTION].page.read(form, f.default, type(f.default) is int)
                for f in dataclasses.fields(cls) if f.metadata[OPTION].page is not None and f.name not in values}
        return cls(**read, **values)

    def to_form(self) -> dict[str, Any]:
        """The fields the web page sends, by their keys in a job request."""
        return {option.page.key: getattr(self, name) for name, option in self.options().items()
                if option.page is not None}


# --- options several actions share -------------------------------------------------------------------------------
DEVICE = Option("auto (GPU when available), cpu or cuda (default auto)", "auto")
SEED = Option("random seed (default 0)", 0, type=non_negative_int)
PRECISIONS = ("auto", "fp32", "bf16", "fp16")
BEATS = Option("beat tracker: learned = a network with a bar decoder (beats and downbeats), dsp = onset tempograms "
               "and dynamic programming, combined = learned, or dsp's beats or half the learned tempo where the "
               f"network supports them clearly better (default {DEFAULT_BEAT_TRACKER})", DEFAULT_BEAT_TRACKER,
               choices=BEAT_TRACKERS)
BEAT_SNAP = Option("keep the pose model's own timing instead of retiming its movement beats onto the song's beats",
                   True)
THREADS = Option("CPU threads for torch (default: torch's choice; 1 is faster on a busy machine)", None,
                 type=positive_int, metavar="N", cli_only=True)
# The video outputs of the frame pipeline `dance` and `render` share.
HEIGHT = Option("output height in pixels, aspect kept, rounded up to even (default: the target video's)", None,
                type=video_height, metavar="H")
CROP = Option("write the model's square crop around the person instead of the whole scene", False)
SKELETON_PREVIEW = Option("also write the skeleton as a video", None, type=output_video, metavar="VIDEO.mp4")
SIDE_BY_SIDE = Option("also write skeleton | generated person side by side", None, type=output_video,
                      metavar="VIDEO.mp4")
# Every trainer's (the protocol of dancesynth.core.runs).
MINUTES = Option("wall-clock training time of the run in all, every call together (a resumed run trains what is "
                 "left); it stops with a checkpoint", None, type=positive_float)
# train-pose's and train-video's config (apps.config_flags): preset < --config < the command's flags < --set.
CONFIG = Option("config settings (TOML, or JSON for a .json name) applied over the preset", None,
                metavar="FILE.toml", cli_only=True)
PRINT_CONFIG = Option("print the config a new run would use, as toml (default) or json, and exit", None,
                      choices=("toml", "json"), metavar="FORMAT", const="toml", cli_only=True)
EPOCHS = Option("total epochs (default: the preset's)", None, type=positive_int)
CHECKPOINT_EVERY = Option("optimizer steps between checkpoints (default 200)", 200, type=positive_int,
                          metavar="STEPS")


def precision_option(what: str) -> Option:
    """``--precision auto|fp32|bf16|fp16`` (default auto) for the arithmetic of ``what`` (e.g. "rendering")."""
    return Option(f"arithmetic of {what}: auto = bf16 on CPUs with AMX or AVX-512-BF16 and on GPUs (fp16 on GPUs "
                  "without bf16), fp32 elsewhere; fp16 needs CUDA (default auto)", "auto", choices=PRECISIONS)


def resume_option(length: str) -> Option:
    """``--resume``; ``length`` is the flag that sets the run's total length (e.g. ``--epochs``)."""
    return Option(f"continue the run in --out exactly where it stopped (Ctrl-C, SIGTERM, kill -9), with its own "
                  f"config and seed; {length} sets a new total", False)


def overrides_option(example: str) -> Option:
    """``--set FIELD=VALUE`` (repeatable, after --config); ``example`` is a FIELD=VALUE shown in the help."""
    return Option(f"override one config field, after --config (repeatable; e.g. --set {example})", (),
                  flag="--set", metavar="FIELD=VALUE", cli_only=True)


def add_trainer_arguments(parser: argparse.ArgumentParser, length: str) -> None:
    """``--resume`` and ``--minutes``, for a trainer without a request type (``length`` as in :func:`resume_option`)."""
    resume_option(length).add_to(parser, "resume")
    MINUTES.add_to(parser, "minutes")


def _method_names() -> tuple[str, ...]:
    from stage1_pose.registry import method_names

    return tuple(method_names())


# --- one request per action --------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class DanceRequest(Request):
    """`dancesynth dance`, :func:`dancesynth.api.dance`, and the page's dance job."""

    COMMAND: ClassVar[str] = "dance"

    song: PathLike = Option("the song (any FFmpeg-readable audio file)", type=existing_file, metavar="SONG",
                            positional=True).field()
    out: PathLike = Option("the dancing video to write", type=output_video, metavar="OUT.mp4").field()
    target: PathLike | None = Option(
        "video of the person to animate (their appearance model is cached or trained now)", None,
        type=existing_file, metavar="VIDEO", one_of="person").field()
    video_model: PathLike | None = Option("stage-2 run folder (from train-video)", None, metavar="RUN",
                                          one_of="person").field()
    train_minutes: float | None = Option(
        "with --target: minutes of appearance training in all (default 30); more continues the cached model; 0 "
        "renders the person's own pixels warped onto the dance at once, untrained", None, type=non_negative_float,
        metavar="M", page=Page("minutes", "training budget (minutes)", 0.0, MINUTES_A_DAY)).field()
    cache: PathLike | None = Option(
        "with --target: appearance-model cache (default ~/.cache/dancesynth/appearance)", None, type=output_folder,
        metavar="DIR").field()
    preset: str | None = Option(
        f"with --target: the appearance model's preset (default auto); {describe_presets(auto=True)}", None,
        choices=preset_names(auto=True)).field()
    pose_model: PathLike | None = Option(
        "stage-1 run folder (from train-pose), or a folder of runs named by method (default: the built-in Dance "
        "Revolution model)", None, metavar="RUN").field()
    method: str | None = Option(
        "which run to use when --pose-model is a folder of runs (default dance_revolution)", None).field()
    seed: int = SEED.field(help="random seed: another seed gives another dance (default 0)",
                           page=Page("seed", "seed", 0, 2**31 - 1))
    start: float = Option("segment start in seconds (default 0)", 0.0, type=non_negative_float, metavar="S",
                          page=Page("start", "segment start (seconds)", 0.0, SECONDS_A_DAY)).field()
    duration: float | None = Option(
        "segment length in seconds (default: to the end of the song)", None, type=positive_float, metavar="D",
        page=Page("duration", "segment duration (seconds)", 1.0, SECONDS_A_DAY)).field()
    height: int | None = HEIGHT.field()
    crop: bool = CROP.field()
    skeleton_preview: PathLike | None = SKELETON_PREVIEW.field()
    side_by_side: PathLike | None = SIDE_BY_SIDE.field()
    precision: str = precision_option("the appearance model's training (with --target) and rendering").field()
    beat_snap: bool = BEAT_SNAP.field()
    device: str = DEVICE.field()
    beats: str = BEATS.field()


@dataclass(frozen=True, kw_only=True)
class RenderRequest(Request):
    """`dancesynth render` and :func:`dancesynth.api.render`."""

    COMMAND: ClassVar[str] = "render"

    poses: PathLike = Option("pose file (.npz, BODY_25)", type=existing_file, metavar="POSES", positional=True).field()
    model: PathLike = Option("run folder written by train-video", metavar="RUN_DIR").field()
    out: PathLike = Option("output video", type=output_video, metavar="VIDEO.mp4").field()
    audio: PathLike | None = Option("audio file to mux (any FFmpeg format)", None, type=existing_file,
                                    metavar="SONG").field()
    normalize: bool = Option("use the poses as they are, without retargeting or normalisation (target canvas)",
                             True).field()
    height: int | None = HEIGHT.field()
    crop: bool = CROP.field()
    skeleton_preview: PathLike | None = SKELETON_PREVIEW.field()
    side_by_side: PathLike | None = SIDE_BY_SIDE.field()
    optimize: bool = Option("plain PyTorch forward (slower, for debugging)", True).field()
    device: str = DEVICE.field()
    precision: str = precision_option("rendering").field()
    threads: int | None = THREADS.field()


@dataclass(frozen=True, kw_only=True)
class GenerateRequest(Request):
    """`dancesynth generate` and :func:`dancesynth.api.generate`."""

    COMMAND: ClassVar[str] = "generate"

    song: PathLike = Option("audio file (mp3, wav, m4a, ... or a video's soundtrack)", type=existing_file,
                            metavar="SONG", positional=True).field()
    model: PathLike | None = Option(
        "run folder from dancesynth train-pose (default: the built-in Dance Revolution model)", None,
        metavar="RUN_DIR").field()
    out: PathLike = Option("output pose file", type=output_file, metavar="POSES.npz").field()
    seed: int = SEED.field(help="random seed of the dance (default 0)")
    preview: PathLike | None = Option("also write a skeleton preview video with the song", None, type=output_video,
                                      metavar="VIDEO.mp4").field()
    precision: str = Option("decoder weights: int8 is ~3x faster on CPU; auto = int8 on CPU, fp32 on GPU", "auto",
                            choices=("auto", "fp32", "int8")).field()
    beat_snap: bool = BEAT_SNAP.field()
    device: str = DEVICE.field()
    beats: str = BEATS.field()


@dataclass(frozen=True, kw_only=True)
class ExtractPosesRequest(Request):
    """`dancesynth extract-poses`, :func:`dancesynth.api.extract_poses`, and the command of the page's preview job.
    Settings left None take :class:`stage2_video.extract.ExtractConfig`'s defaults (not imported here: --help stays
    fast)."""

    COMMAND: ClassVar[str] = "extract-poses"

    video: PathLike = Option("input video (any resolution; phone rotation is honoured)", type=existing_file,
                             positional=True).field()
    out: PathLike = Option("output pose file (.npz)", type=output_file, metavar="POSES.npz").field()
    preview: PathLike | None = Option("also write this mp4: the skeleton drawn over the video", None,
                                      type=output_video, metavar="OVERLAY.mp4").field()
    smoothing: str = Option("temporal filter: savgol (no lag, default), one-euro (causal) or none", "savgol").field()
    window_s: float | None = Option("savgol window length in seconds (default 0.2)", None, type=positive_float,
                                    metavar="SECONDS", flag="--window").field()
    min_cutoff_hz: float | None = Option("one-euro cut-off at rest in Hz, lower = smoother (default 1.0)", None,
                                         type=positive_float, metavar="HZ", flag="--min-cutoff").field()
    beta: float | None = Option("one-euro speed coefficient, higher = less lag on fast moves (default 20)", None,
                                type=non_negative_float, metavar="B").field()
    spike_window_s: float | None = Option(
        "a joint that leaps away and back within this many seconds is swapped back (arms or legs swapped by the "
        "estimator) or dropped and filled in, before the filter; 0 = off (default 0.12)", None,
        type=non_negative_float, metavar="SECONDS", flag="--spike-window").field()
    min_visibility: float | None = Option("BlazePose visibility below which a joint counts as absent (default 0.5)",
                                          None, type=fraction, metavar="V").field()
    max_missing: float | None = Option(
        "fail when the person is missing in more than this fraction of frames (default 0.5)", None, type=fraction,
        metavar="FRACTION").field()


@dataclass(frozen=True, kw_only=True)
class TrainVideoRequest(Request):
    """`dancesynth train-video`, :func:`dancesynth.api.train_video` (the command turns --size, --batch-size,
    --config and --set into its ``overrides``), and the command of the page's training job (whose page sends the
    minutes more, which the server adds to the minutes trained: see ``apps.web.server``)."""

    COMMAND: ClassVar[str] = "train-video"

    video: PathLike = Option("video of the target person (any FFmpeg format)", type=existing_file,
                             metavar="TARGET_VIDEO", positional=True).field()
    out: PathLike = Option("run folder for checkpoints and logs", type=output_folder, metavar="RUN_DIR").field()
    preset: str = Option(f"the model's preset (default small); {describe_presets()}", "small",
                         choices=preset_names()).field()
    size: str | None = Option("model resolution override, e.g. 256x256 (multiple of 8)", None, metavar="WxH",
                              cli_only=True).field()
    epochs: int | None = EPOCHS.field(help="total epochs (default: the preset's 100 + 100 decaying)")
    resume: bool = resume_option("--epochs").field()
    minutes: float | None = MINUTES.field()
    batch_size: int | None = Option("consecutive-frame pairs per step (preset default)", None, type=positive_int,
                                    cli_only=True).field()
    poses: PathLike | None = Option("poses of TARGET_VIDEO to use instead of extracting", None, type=existing_file,
                                    metavar="POSES.npz").field()
    vgg_weights: PathLike | None = Option("local torchvision vgg19 weights (.pth/.safetensors)", None,
                                          type=existing_file, metavar="FILE").field()
    checkpoint_every: int = CHECKPOINT_EVERY.field()
    sample_every: int = Option("optimizer steps between sample grids (default 200)", 200, type=positive_int,
                               metavar="STEPS").field()
    seed: int = SEED.field()
    device: str = DEVICE.field()
    precision: str = precision_option("the forward passes (weights stay float32)").field()
    threads: int | None = THREADS.field()
    config: str | None = CONFIG.field()
    overrides: tuple[str, ...] = overrides_option("lambda_l1=5").field()
    print_config: str | None = PRINT_CONFIG.field()


@dataclass(frozen=True, kw_only=True)
class TrainPoseRequest(Request):
    """`dancesynth train-pose` and :func:`dancesynth.api.train_pose` (the command resolves --config and --set into
    its ``overrides``)."""

    COMMAND: ClassVar[str] = "train-pose"

    method: str = Option("the stage-1 method", choices=_method_names).field()
    data: PathLike = Option("dataset folder (dancesynth make-dataset)", metavar="DIR").field()
    out: PathLike = Option("run folder for the model and logs", type=output_folder, metavar="RUN_DIR").field()
    preset: str = Option("config preset: small (CPU) or paper (default small)", "small").field()
    config: str | None = CONFIG.field()
    overrides: tuple[str, ...] = overrides_option("hidden=256").field()
    print_config: str | None = PRINT_CONFIG.field()
    epochs: int | None = EPOCHS.field()
    resume: bool = resume_option("--epochs").field()
    minutes: float | None = MINUTES.field()
    batch_size: int | None = Option("global batch size in windows (default: the preset's)", None,
                                    type=positive_int).field()
    window: int | None = Option("training window length in pose frames", None, type=positive_int,
                                metavar="FRAMES").field()
    checkpoint_every: int = CHECKPOINT_EVERY.field()
    preview_every: int = Option("epochs between preview videos, 0 = no previews (default 10)", 10,
                                type=non_negative_int, metavar="EPOCHS").field()
    preview_gap: float = Option("skip a due preview when the last one is less than this long ago (default 2)", 2.0,
                                type=non_negative_float, metavar="MINUTES").field()
    seed: int = SEED.field()
    workers: int = Option("data loader worker processes (default 0)", 0, type=non_negative_int).field()
    device: str = DEVICE.field()


@dataclass(frozen=True, kw_only=True)
class DemoRequest(Request):
    """`dancesynth demo`, :func:`apps.demo.run_demo`, and the page's demo job."""

    COMMAND: ClassVar[str] = "demo"

    out: PathLike = Option("output folder (default demo_output)", "demo_output", type=output_folder,
                           metavar="DIR").field()
    minutes: float = Option("total time budget in minutes (default 15)", 15.0, type=positive_float,
                            page=Page("minutes", "demo's time budget (minutes)", 1.01, MINUTES_A_DAY)).field()
    seed: int = SEED.field()
    device: str = DEVICE.field()
