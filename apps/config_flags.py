"""The config flags every training command shares: ``--config FILE``, ``--set FIELD=VALUE`` and
``--print-config``, applied over a preset in that order (preset < file < --set)."""

from __future__ import annotations

import argparse
from typing import Any, TypeVar

from dancesynth.core.config import apply_overrides, format_config, load_config_file, update_config

C = TypeVar("C")


def add_config_arguments(parser: argparse.ArgumentParser, set_example: str) -> None:
    """Add ``--config``, ``--set`` (repeatable, into ``args.overrides``) and ``--print-config`` to ``parser``;
    ``set_example`` is a FIELD=VALUE shown in the help."""
    parser.add_argument("--config", metavar="FILE.toml",
                        help="config settings (TOML, or JSON for a .json name) applied over the preset")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", dest="overrides",
                        help=f"override one config field, after --config (repeatable; e.g. --set {set_example})")
    parser.add_argument("--print-config", nargs="?", const="toml", choices=("toml", "json"), metavar="FORMAT",
                        help="print the config a new run would use, as toml (default) or json, and exit")


def resolve_config(preset: C, args: argparse.Namespace, flags: dict[str, Any] | None = None) -> C:
    """``preset`` with ``args.config``'s settings, then ``flags`` (fields set by a command's own options such
    as --batch-size), then ``args.overrides`` (--set) applied."""
    config = update_config(preset, load_config_file(args.config)) if args.config else preset
    return apply_overrides(update_config(config, flags or {}), args.overrides)


def print_config(config: Any, fmt: str) -> None:
    """Write ``config`` to stdout as ``fmt`` (toml or json); ``--config`` reads the text back."""
    print(format_config(config, fmt), end="")
