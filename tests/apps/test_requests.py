"""One definition per user action (apps/requests.py): every request survives its command line and its page form,
and each API function has exactly its request's fields, defaults and documented arguments."""

import dataclasses
import inspect
import re
import shlex

import pytest

import dancesynth.api
from apps import demo
from apps.cli import build_parser
from apps.requests import (
    DanceRequest,
    DemoRequest,
    ExtractPosesRequest,
    GenerateRequest,
    RenderRequest,
    TrainPoseRequest,
    TrainVideoRequest,
)
from apps.web.server import JOB_FIELDS, TRAIN_MORE, TRAIN_MORE_DEFAULT
from dancesynth.core.errors import DancesynthError
from stage1_pose.registry import method_names
from stage2_video.presets import preset_names

# Each request's API function, and the parameters it has besides the request's fields: the trainers' config
# overrides (the command resolves --config and --set into them), the demo's sizes (the web server's plan).
API = {DanceRequest: (dancesynth.api.dance, ()), RenderRequest: (dancesynth.api.render, ()),
       GenerateRequest: (dancesynth.api.generate, ()), ExtractPosesRequest: (dancesynth.api.extract_poses, ()),
       TrainVideoRequest: (dancesynth.api.train_video, ("overrides",)),
       TrainPoseRequest: (dancesynth.api.train_pose, ("overrides",)), DemoRequest: (demo.run_demo, ("plan",))}
# The page's job kinds and the request each one's fields belong to (a training job's one field, its minutes more,
# is the server's own: test_a_training_jobs_minutes_more_are_read_from_its_form).
PAGE_JOBS = {"dance": DanceRequest, "demo": DemoRequest}


def _file(path, content=b"x"):
    path.write_bytes(content)
    return str(path)


def _requests(tmp):
    """A request of every action with every field away from its default (of a group of alternatives, one)."""
    song, video, poses = _file(tmp / "song.wav"), _file(tmp / "me.mp4"), _file(tmp / "dance.npz")
    out = str(tmp / "out.mp4")
    return [
        DanceRequest(song=song, out=out, target=video, train_minutes=12.5, cache=str(tmp / "cache"), preset="medium",
                     pose_model="runs/pose", method="lstm", seed=7, start=3.25, duration=10.0, height=480, crop=True,
                     skeleton_preview=str(tmp / "s.mp4"), side_by_side=str(tmp / "b.mp4"), precision="bf16",
                     beat_snap=False, device="cpu", beats="dsp"),
        DanceRequest(song=song, out=out, video_model="runs/person with space"),
        RenderRequest(poses=poses, model="runs/person", out=out, audio=song, normalize=False, height=720, crop=True,
                      skeleton_preview=str(tmp / "s.mp4"), side_by_side=str(tmp / "b.mp4"), optimize=False,
                      device="cpu", precision="fp32", threads=2),
        GenerateRequest(song=song, model="runs/dr", out=str(tmp / "p.npz"), seed=3, preview=str(tmp / "v.mp4"),
                        precision="int8", beat_snap=False, device="cpu", beats="dsp"),
        ExtractPosesRequest(video=video, out=str(tmp / "p.npz"), preview=str(tmp / "o.mp4"), smoothing="one-euro",
                            window_s=0.3, min_cutoff_hz=2.0, beta=10.0, spike_window_s=0.0, min_visibility=0.25,
                            max_missing=0.75),
        TrainVideoRequest(video=video, out=str(tmp / "run"), preset="medium", size="256x256", epochs=3, resume=True,
                          minutes=1.5, batch_size=2, poses=poses, vgg_weights=poses, checkpoint_every=10,
                          sample_every=20, seed=1, device="cpu", precision="bf16", threads=1, config="m.toml",
                          overrides=("ngf=64", "n_blocks=6"), print_config="json"),
        TrainPoseRequest(method=method_names()[-1], data="data/synth", out=str(tmp / "run"), preset="paper",
                         config="m.toml", overrides=("hidden=256",), print_config="toml", epochs=4, resume=True,
                         minutes=0.5, batch_size=8, window=60, checkpoint_every=5, preview_every=0, preview_gap=0.5,
                         seed=2, workers=1, device="cpu"),
        DemoRequest(out=str(tmp / "demo"), minutes=2.5, seed=4, device="cpu"),
    ]


def test_the_samples_set_every_field_of_every_action(tmp_path):
    """So that a field added to a request is round-tripped below too."""
    requests = _requests(tmp_path)
    assert {type(r) for r in requests} == set(API)
    for cls in API:
        samples = [r for r in requests if type(r) is cls]
        for name, option in cls.options().items():
            assert any(getattr(r, name) != option.default for r in samples), (cls.COMMAND, name)


def test_every_request_survives_its_command_line(tmp_path):
    """request -> equivalent command -> the real `dancesynth` parser -> the same request."""
    for request in _requests(tmp_path):
        argv = shlex.split(shlex.join(request.to_command()))
        assert argv[:2] == ["dancesynth", request.COMMAND]
        args = build_parser().parse_args(argv[1:])
        assert args.command == request.COMMAND
        assert type(request).from_namespace(args) == request


def test_the_command_line_leaves_defaults_out(tmp_path):
    song = _file(tmp_path / "song.wav")
    request = DanceRequest(song=song, out="dance.mp4", video_model="runs/me")
    assert request.to_command() == ["dancesynth", "dance", song, "--out", "dance.mp4", "--video-model", "runs/me"]
    assert DemoRequest().to_command() == ["dancesynth", "demo"]


def test_every_command_parses_into_its_request_with_the_defaults(tmp_path):
    """What a bare command line means is the request type's defaults."""
    song = _file(tmp_path / "song.wav")
    args = build_parser().parse_args(["dance", song, "--target", song, "--out", "o.mp4"])
    assert DanceRequest.from_namespace(args) == DanceRequest(song=song, target=song, out="o.mp4")
    assert DemoRequest.from_namespace(build_parser().parse_args(["demo"])) == DemoRequest()


@pytest.mark.parametrize("kind", PAGE_JOBS)
def test_every_page_job_survives_its_form(tmp_path, kind):
    """request -> the page's form (JSON numbers, or text as its inputs send them) -> request, and the form's keys are
    fields the server takes for that kind of job."""
    cls = PAGE_JOBS[kind]
    request = next(r for r in _requests(tmp_path) if type(r) is cls)
    form = request.to_form()
    assert form and set(form) <= set(JOB_FIELDS[kind])
    on_page = {name for name, option in cls.options().items() if option.page is not None}
    rest = {name: value for name, value in dataclasses.asdict(request).items() if name not in on_page}
    for sent in (form, {key: str(value) for key, value in form.items()}):
        assert cls.from_form(sent, **rest) == request


def test_a_page_field_out_of_its_range_is_a_sentence():
    with pytest.raises(DancesynthError, match=r"^The seed must be a whole number, got 1.5\.$"):
        DanceRequest.from_form({"seed": 1.5}, song="s.wav", out="o.mp4", video_model="m")
    with pytest.raises(DancesynthError, match=r"^The segment duration \(seconds\) must be between 1 and 86400, "
                                              r"got '0.5'\.$"):
        DanceRequest.from_form({"duration": "0.5"}, song="s.wav", out="o.mp4", video_model="m")


def test_a_training_jobs_minutes_more_are_read_from_its_form():
    """A training job's minutes are minutes more, read apart from its TrainVideoRequest (whose minutes are the
    run's in all), as a JSON number or the page's text, 10 when not sent, out of range a sentence."""
    assert TRAIN_MORE.key in JOB_FIELDS["train"]
    for sent in (2.5, "2.5", " 2.5 "):
        assert TRAIN_MORE.read({"minutes": sent}, TRAIN_MORE_DEFAULT, integer=False) == 2.5
    assert TRAIN_MORE.read({}, TRAIN_MORE_DEFAULT, integer=False) == 10.0
    with pytest.raises(DancesynthError, match=r"^The training budget \(minutes\) must be between 0.05 and 1440, "
                                              r"got 0.01\.$"):
        TRAIN_MORE.read({"minutes": 0.01}, TRAIN_MORE_DEFAULT, integer=False)


@pytest.mark.parametrize("cls", API, ids=lambda cls: cls.COMMAND)
def test_each_api_function_has_its_requests_fields_defaults_and_documentation(cls):
    function, extra = API[cls]
    parameters = inspect.signature(function).parameters
    fields = {name: option for name, option in cls.options().items() if not option.cli_only}
    assert set(parameters) == {*fields, *extra}
    for name, option in fields.items():
        # A required field of the command may be optional in Python (generate's out: the dance is returned).
        if option.default is not dataclasses.MISSING:
            assert parameters[name].default == option.default, (cls.COMMAND, name)
        assert re.search(rf"\b{name}\b", function.__doc__), f"{function.__name__}'s docstring does not say {name}"


def test_api_dance_hands_the_pipeline_its_request(monkeypatch):
    made = []
    monkeypatch.setattr("apps.pipeline.dance", made.append)
    dancesynth.api.dance("song.wav", out="o.mp4", video_model="m", seed=3)
    assert made == [DanceRequest(song="song.wav", out="o.mp4", video_model="m", seed=3)]


def test_a_training_at_every_preset_gives_a_command_train_video_accepts(tmp_path):
    """The page's "equivalent command" of a training once said --preset medium, which train-video refused."""
    video = _file(tmp_path / "me.mp4")
    for preset in preset_names():
        request = TrainVideoRequest(video=video, out=str(tmp_path / "run"), preset=preset, minutes=11.0, resume=True)
        args = build_parser().parse_args(request.to_command()[1:])
        assert TrainVideoRequest.from_namespace(args) == request

