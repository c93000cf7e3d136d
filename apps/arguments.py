"""Checks shared by every command's arguments, run by argparse before any work starts.

Each ``type=`` function takes the text given on the command line and returns the value (paths stay strings)
or raises :class:`argparse.ArgumentTypeError` with what is wrong; :class:`ArgumentParser` turns that, like every
other argument error, into one line and exit status 1 (see :func:`apps.cli.main`).
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

from dancesynth.core.fileio import not_a_folder, special_file

# Counts go to C ints in torch and numpy; nothing a user means is larger.
MAX_INT = 2**31 - 1


class UsageError(Exception):
    """A bad command line; its text is the whole line to print (``dancesynth CMD: error: ...``)."""


class ArgumentParser(argparse.ArgumentParser):
    """An argument parser whose errors raise :class:`UsageError` (one line) instead of printing usage and exiting 2."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: error: {message} (see `{self.prog} --help`).")


def _number(text: str, kind: type) -> int | float:
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a {'whole ' if kind is int else ''}number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    if abs(value) > MAX_INT:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_INT}, got {text!r}")
    return value


def _checked(kind: type, accept: Callable[[float], bool], says: str, doc: str) -> Callable[[str], int | float]:
    """A ``type=`` function reading a ``kind`` number and refusing values ``accept`` rejects with ``says``."""

    def parse(text: str) -> int | float:
        value = _number(text, kind)
        if not accept(value):
            raise argparse.ArgumentTypeError(f"{says}, got {text!r}")
        return value

    parse.__doc__ = doc
    return parse


positive_int = _checked(int, lambda v: v >= 1, "must be positive",
                        "A whole number of at least 1 (epochs, batch size, steps, threads).")
# 8K: H.264 levels end there, and larger frames of the whole scene would not fit in memory anyway.
MAX_VIDEO_HEIGHT = 4320
video_height = _checked(int, lambda v: 16 <= v <= MAX_VIDEO_HEIGHT, f"must be 16 to {MAX_VIDEO_HEIGHT} pixels",
                        "An output video height in pixels.")
non_negative_int = _checked(int, lambda v: v >= 0, "must be 0 or more",
                            'A whole number of at least 0 (seeds, worker counts, "0 = off" periods).')
positive_float = _checked(float, lambda v: v > 0, "must be positive",
                          "A finite number greater than 0 (seconds, minutes, frame rates).")
non_negative_float = _checked(float, lambda v: v >= 0, "must be 0 or more",
                              "A finite number of at least 0 (start times, tolerances).")
fraction = _checked(float, lambda v: 0 <= v <= 1, "must be between 0 and 1", "A number from 0 to 1.")
tcp_port = _checked(int, lambda v: 1 <= v <= 65535, "must be a port from 1 to 65535", "A TCP port number.")


def existing_file(text: str) -> str:
    """A file that exists, can be read and is not empty."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder, not a file; give the path of the file itself")
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text} does not exist; check the path")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text} is not a regular file; give the path of a file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text} cannot be read (permission denied)")
    if path.stat().st_size == 0:
        raise argparse.ArgumentTypeError(f"{text} is empty (0 bytes); give a complete file")
    return text


def _writable_folder(folder: Path, text: str) -> None:
    if not os.access(folder, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"cannot write {text}: the folder {folder} is read-only or not yours")


def output_file(text: str) -> str:
    """A file to write: not a folder, a device, a named pipe or a socket, in an existing folder that may be written
    to. (That it is none of the command's inputs, nor another output, is checked by
    :func:`dancesynth.core.fileio.check_outputs` once all arguments are known.)"""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder; give the path of the file to write instead")
    kind = special_file(path)
    if kind is not None:
        raise argparse.ArgumentTypeError(f"{text} is {kind}; give the path of a file to write instead")
    folder = path.parent
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"cannot write {text}: the folder {folder} does not exist; create it first")
    _writable_folder(folder, text)
    return text


def output_folder(text: str) -> str:
    """A folder to create or write into: not a file, a device, a named pipe or a socket, and its nearest existing
    folder may be written to. (That it neither is nor holds one of the command's inputs is checked by
    :func:`dancesynth.core.fileio.check_outputs` once all arguments are known.)"""
    path = Path(text).absolute()
    kind = not_a_folder(path)
    if kind is not None:
        raise argparse.ArgumentTypeError(f"{text} is {kind}; give a folder path")
    existing = next(p for p in (path, *path.parents) if p.exists())
    if not existing.is_dir():
        raise argparse.ArgumentTypeError(f"cannot create {text}: {existing} is a file, not a folder")
    _writable_folder(existing, text)
    return text


def add_precision_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """``--precision auto|fp32|bf16|fp16`` (default auto) for the arithmetic of ``what`` (e.g. "rendering")."""
    parser.add_argument("--precision", choices=("auto", "fp32", "bf16", "fp16"), default="auto",
                        help=f"arithmetic of {what}: auto = bf16 on CPUs with AMX or AVX-512-BF16 and on GPUs "
                             "(fp16 on GPUs without bf16), fp32 elsewhere; fp16 needs CUDA (default auto)")


def add_output_arguments(parser: argparse.ArgumentParser) -> None:
    """The video outputs of the frame pipeline `dance` and `render` share: ``--height``, ``--crop``,
    ``--skeleton-preview`` and ``--side-by-side``."""
    parser.add_argument("--height", type=video_height, default=None, metavar="H",
                        help="output height in pixels, aspect kept, rounded up to even (default: the target video's)")
    parser.add_argument("--crop", action="store_true",
                        help="write the model's square crop around the person instead of the whole scene")
    parser.add_argument("--skeleton-preview", type=output_file, default=None, metavar="PATH",
                        help="also write the skeleton as a video")
    parser.add_argument("--side-by-side", type=output_file, default=None, metavar="PATH",
                        help="also write skeleton | generated person side by side")


def add_beats_argument(parser: argparse.ArgumentParser) -> None:
    """``--beats learned|dsp``: the beat tracker for the song (default: the better one on the beat benchmark)."""
    from stage1_pose.beat_tracking.trackers import BEAT_TRACKERS, DEFAULT_BEAT_TRACKER

    parser.add_argument("--beats", choices=BEAT_TRACKERS, default=DEFAULT_BEAT_TRACKER,
                        help="beat tracker: learned = a network with a bar decoder (beats and downbeats), dsp = "
                             f"onset tempograms and dynamic programming (default {DEFAULT_BEAT_TRACKER})")


def add_trainer_arguments(parser: argparse.ArgumentParser, length: str) -> None:
    """``--resume`` and ``--minutes``, alike on every trainer (the protocol of :mod:`dancesynth.core.runs`);
    ``length`` is the flag that sets the run's total length (e.g. ``--epochs``)."""
    parser.add_argument("--resume", action="store_true",
                        help=f"continue the run in --out exactly where it stopped (Ctrl-C, SIGTERM, kill -9), with its "
                             f"own config and seed; {length} sets a new total")
    parser.add_argument("--minutes", type=positive_float,
                        help="wall-clock training time of the run in all, every call together (a resumed run trains "
                             "what is left); it stops with a checkpoint")
