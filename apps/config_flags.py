"""The config flags every training command shares: ``--config FILE``, ``--set FIELD=VALUE`` and
``--print-config``, applied over a preset in that order (preset < file < --set)."""

from __future__ import annotations

import argparse
from typing import Any, TypeVar

from dancesynth.core.config import (
    apply_overrides,
    config_to_dict,
    format_config,
    load_config_file,
    parse_overrides,
    update_config,
)

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


def chosen_fields(preset: Any, config: Any, args: argparse.Namespace,
                  flags: dict[str, Any] | None = None) -> dict[str, Any]:
    """The fields of :func:`resolve_config`'s ``config`` that the user chose: named in the config file, the
    command's flags or --set, or differing from ``preset``. The others stay free for a trainer's own choices made
    from the data (e.g. the appearance model's background condition for a person crossing the scene)."""
    named = {**(load_config_file(args.config) if args.config else {}), **(flags or {}),
             **parse_overrides(args.overrides)}
    defaults = config_to_dict(preset)
    return {k: v for k, v in config_to_dict(config).items() if k in named or v != defaults.get(k)}


def print_config(config: Any, fmt: str) -> None:
    """Write ``config`` to stdout as ``fmt`` (toml or json); ``--config`` reads the text back."""
    print(format_config(config, fmt), end="")
