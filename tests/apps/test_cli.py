import argparse
import importlib
import logging
import pkgutil
import subprocess
import sys
from importlib.metadata import version

import pytest

from apps import cli, commands
from apps.cli import main
from apps.logs import configure_logging

COMMANDS = sorted(importlib.import_module(f"apps.commands.{m.name}").NAME
                  for m in pkgutil.iter_modules(commands.__path__))
HEAVY = ("torch", "numpy", "scipy", "cv2", "librosa", "av", "mediapipe", "matplotlib")


def _help(argv: list[str], capsys) -> str:
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 0
    return capsys.readouterr().out


def test_version_is_the_installed_one(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"dancesynth {version('dancesynth')}"


def test_help_lists_every_command(capsys):
    text = _help(["--help"], capsys)
    for command in COMMANDS:
        assert f"\n    {command}" in text


def test_help_imports_none_of_the_heavy_libraries():
    """`dancesynth --help` and every command's --help come back at once: no torch, numpy or codecs imported."""
    script = ("import contextlib, io, sys\n"
              "from apps.cli import main\n"
              f"for argv in [['--help'], *[[c, '--help'] for c in {COMMANDS!r}]]:\n"
              "    with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
              "        main(argv)\n"
              f"print([m for m in {HEAVY!r} if m in sys.modules])\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_every_command_takes_quiet_and_verbose(capsys):
    for command in COMMANDS:
        text = _help([command, "--help"], capsys)
        assert "-q, --quiet" in text and "-v, --verbose" in text, command


@pytest.fixture
def chatty_command(monkeypatch):
    """make-dataset replaced by a command that logs at every level, as the libraries do."""
    from apps.commands import make_dataset

    def run(args):
        logging.getLogger("stage1_pose.somewhere").debug("a debug detail")
        logging.getLogger("apps.commands.make_dataset").info("wrote result.npz")
        logging.getLogger("stage2_video.somewhere").warning("something to know")
        logging.getLogger("matplotlib").info("another library's chatter")

    monkeypatch.setattr(make_dataset, "run", run)
    yield ["make-dataset", "--out", "unused"]
    configure_logging(logging.INFO)


def test_quiet_and_verbose_set_what_reaches_stderr(chatty_command, capsys):
    assert main(chatty_command) == 0
    captured = capsys.readouterr()
    assert captured.err == "wrote result.npz\nwarning: something to know\n" and captured.out == ""

    assert main([*chatty_command, "-q"]) == 0
    assert capsys.readouterr().err == "warning: something to know\n"

    assert main([*chatty_command, "--verbose"]) == 0
    assert capsys.readouterr().err == "debug: a debug detail\nwrote result.npz\nwarning: something to know\n"


def test_quiet_and_verbose_together_is_a_usage_error(capsys):
    assert main(["make-dataset", "--out", "x", "-q", "-v"]) != 0
    assert "not allowed with argument" in capsys.readouterr().err


def test_every_preset_option_offers_its_model_familys_presets():
    """Each --preset (and evaluate's --classifier-preset) offers exactly its registry's names, plus auto where the
    command resolves it; train-pose's depend on --method and are checked when its config is made."""
    from stage1_pose.models.ren.stgcn import STGCN_PRESETS
    from stage1_pose.style_classifier import PRESETS as STYLE_PRESETS
    from stage2_video.models.pix2pixhd import PRESETS as VIDEO_PRESETS

    subcommands = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    offered = {(command, option): None if action.choices is None else sorted(action.choices)
               for command, parser in subcommands.choices.items() for action in parser._actions
               for option in action.option_strings if option.endswith("-preset")}
    assert offered == {("dance", "--preset"): sorted(["auto", *VIDEO_PRESETS]),
                       ("train-video", "--preset"): sorted(VIDEO_PRESETS),
                       ("train-stgcn", "--preset"): sorted(STGCN_PRESETS),
                       ("train-style-classifier", "--preset"): sorted(STYLE_PRESETS),
                       ("evaluate", "--classifier-preset"): sorted(STYLE_PRESETS),
                       ("train-pose", "--preset"): None}


def test_every_command_that_tracks_beats_offers_both_trackers(tmp_path, capsys):
    """--beats is on generate, dance, prepare and import-dance, with the same choices and default; a wrong name is
    one line and exit 1."""
    from stage1_pose.beat_tracking.trackers import BEAT_TRACKERS, DEFAULT_BEAT_TRACKER

    subcommands = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    offered = {command: (tuple(action.choices), action.default) for command, parser in subcommands.choices.items()
               for action in parser._actions if "--beats" in action.option_strings}
    assert offered == {c: (BEAT_TRACKERS, DEFAULT_BEAT_TRACKER) for c in ("dance", "generate", "import-dance",
                                                                            "prepare")}
    song = tmp_path / "song.wav"
    song.write_bytes(b"RIFF")
    out = str(tmp_path / "p.npz")
    assert cli.build_parser().parse_args(["generate", str(song), "--out", out, "--beats", "dsp"]).beats == "dsp"
    assert cli.main(["generate", str(song), "--out", out, "--beats", "oracle"]) == 1
    assert "invalid choice: 'oracle'" in capsys.readouterr().err
