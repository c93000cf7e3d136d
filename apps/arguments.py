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

from dancesynth.core.fileio import misnamed_video, not_a_folder, special_file

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


def output_video(text: str) -> str:
    """:func:`output_file` for a video, named as the MP4 it will be
    (:func:`dancesynth.core.fileio.misnamed_video`)."""
    output_file(text)
    if misnamed_video(text):
        raise argparse.ArgumentTypeError(f"{text} would hold an MP4 video; give a name ending in .mp4")
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


# The checks whose value is a path: the Python API checks its paths itself (check_outputs, check_video_names).
PATH_CHECKS = (existing_file, output_file, output_video, output_folder)
