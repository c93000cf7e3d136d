"""The config of a training command from its flags ``--config FILE``, ``--set FIELD=VALUE`` and ``--print-config``
(options of :mod:`apps.requests`), applied over a preset in that order (preset < file < --set)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar

from dancesynth.core.config import (
    apply_overrides,
    config_to_dict,
    format_config,
    load_config_file,
    parse_overrides,
    update_config,
)

if TYPE_CHECKING:
    from apps.requests import TrainPoseRequest, TrainVideoRequest

    Trainer = TrainPoseRequest | TrainVideoRequest

C = TypeVar("C")


def resolve_config(preset: C, request: Trainer, flags: dict[str, Any] | None = None) -> C:
    """``preset`` with ``request.config``'s settings, then ``flags`` (fields set by a command's own options such
    as --batch-size), then ``request.overrides`` (--set) applied."""
    config = update_config(preset, load_config_file(request.config)) if request.config else preset
    return apply_overrides(update_config(config, flags or {}), list(request.overrides))


def chosen_fields(preset: Any, config: Any, request: Trainer,
                  flags: dict[str, Any] | None = None) -> dict[str, Any]:
    """The fields of :func:`resolve_config`'s ``config`` that the user chose: named in the config file, the
    command's flags or --set, or differing from ``preset``. The others stay free for a trainer's own choices made
    from the data (e.g. the appearance model's background condition for a person crossing the scene)."""
    named = {**(load_config_file(request.config) if request.config else {}), **(flags or {}),
             **parse_overrides(list(request.overrides))}
    defaults = config_to_dict(preset)
    return {k: v for k, v in config_to_dict(config).items() if k in named or v != defaults.get(k)}


def print_config(config: Any, fmt: str) -> None:
    """Write ``config`` to stdout as ``fmt`` (toml or json); ``--config`` reads the text back."""
    print(format_config(config, fmt), end="")
