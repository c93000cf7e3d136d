"""The `dancesynth` command: one entry point, one subcommand per module in :mod:`apps.commands`.

Each command module defines ``NAME``, ``HELP`` (one line), ``DESCRIPTION`` (the --help text),
``add_arguments(parser)`` and ``run(args)``. Modules are discovered, so adding a command is adding a file.
Command modules import only the standard library at module level (heavy imports go inside ``run``), so
``dancesynth --help`` and argument errors come back at once.

Every command takes -q/--quiet (warnings and errors only, no progress) and -v/--verbose (debug messages too, and
the lines native libraries such as mediapipe write to stderr, hidden otherwise).
Messages and progress go to stderr through :mod:`logging`; errors end the command with exit status 1.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import pkgutil
import signal
import sys
from pathlib import Path

from apps import commands
from apps.arguments import ArgumentParser, UsageError
from apps.logs import configure_logging
from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import os_error_sentence

LEVELS = {"quiet": logging.WARNING, None: logging.INFO, "verbose": logging.DEBUG}


def _verbosity() -> argparse.ArgumentParser:
    """The -q/-v options every command inherits."""
    parent = argparse.ArgumentParser(add_help=False)
    group = parent.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", dest="verbosity", action="store_const", const="quiet",
                       help="show only warnings and errors (no progress)")
    group.add_argument("-v", "--verbose", dest="verbosity", action="store_const", const="verbose",
                       help="also show debug messages and native libraries' log lines (mediapipe's)")
    return parent


def build_parser() -> argparse.ArgumentParser:
    from dancesynth import __version__

    parser = ArgumentParser(
        prog="dancesynth",
        description="Turn a song and a video of a person into a video of that person dancing to the song.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    parents = [_verbosity()]
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.DESCRIPTION, parents=parents,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
        p.set_defaults(handler=module.run)
    return parser


def _terminated(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM cleans up (partial outputs deleted) exactly like Ctrl-C


def _remove_empty_folders(folder: Path) -> None:
    """Delete ``folder`` and the folders inside it if they hold no file (what a failed command created)."""
    if not folder.is_dir() or folder.is_symlink():
        return
    for inner in sorted((p for p in folder.rglob("*") if p.is_dir() and not p.is_symlink()), reverse=True):
        if not any(inner.iterdir()):
            inner.rmdir()
    if not any(folder.iterdir()):
        folder.rmdir()


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except UsageError as e:
        print(e, file=sys.stderr)
        return 1
    configure_logging(LEVELS[args.verbosity])
    out = getattr(args, "out", None)
    new_out = Path(out) if out and not os.path.lexists(out) else None
    previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        args.handler(args)
    except (DancesynthError, OSError, KeyboardInterrupt) as e:
        if new_out is not None:
            _remove_empty_folders(new_out)
        if isinstance(e, KeyboardInterrupt):
            print(f"dancesynth {args.command}: interrupted.", file=sys.stderr)
            return 130
        message = e if isinstance(e, DancesynthError) else os_error_sentence(e)
        print(f"dancesynth {args.command}: error: {message}", file=sys.stderr)
        return 1
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0


if __name__ == "__main__":
    sys.exit(main())
