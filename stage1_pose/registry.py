"""The registry of stage-1 methods: name -> method class and its named config presets.

Entries are import paths, loaded on first use, so a method whose module needs extra pieces (e.g. Ren's
ST-GCN) costs nothing to the others. A method module defines a :class:`Stage1Method` subclass and a dict of
presets (at least ``small`` and ``paper``) whose values are instances of its frozen config dataclass.
"""

from __future__ import annotations

import dataclasses
import importlib
import typing
from dataclasses import dataclass
from typing import Any

from dancesynth.core.errors import DancesynthError
from stage1_pose.models.base import Stage1Method


@dataclass(frozen=True)
class MethodEntry:
    """Where a method lives: ``module`` path, its Stage1Method class name and its presets dict name."""

    module: str
    method_class: str
    presets: str


METHODS: dict[str, MethodEntry] = {
    "dancing2music": MethodEntry("stage1_pose.models.dancing2music.model", "Dancing2MusicMethod", "DANCING2MUSIC_PRESETS"),
    "dance_revolution": MethodEntry("stage1_pose.models.dance_revolution.model", "DanceRevolution", "DANCE_REVOLUTION_PRESETS"),
    "lstm": MethodEntry("stage1_pose.models.lstm.model", "LSTMBaseline", "LSTM_PRESETS"),
    "ren": MethodEntry("stage1_pose.models.ren.model", "RenMethod", "REN_PRESETS"),
}


def method_names() -> list[str]:
    """Registered method names, sorted."""
    return sorted(METHODS)


def load_method(name: str) -> tuple[type[Stage1Method], dict[str, Any]]:
    """``(method class, presets)`` of method ``name``."""
    if name not in METHODS:
        raise DancesynthError(f"Unknown method {name!r}; choose one of {', '.join(method_names())}.")
    entry = METHODS[name]
    module = importlib.import_module(entry.module)
    return getattr(module, entry.method_class), getattr(module, entry.presets)


def _convert(value: Any, annotation: Any) -> Any:
    """JSON / command-line value -> the field's type (lists become tuples, strings are parsed)."""
    origin = typing.get_origin(annotation)
    if origin is tuple:
        item = typing.get_args(annotation)[0]
        items = value.split(",") if isinstance(value, str) else value
        return tuple(_convert(v, item) for v in items)
    if isinstance(value, str) and annotation in (int, float):
        return annotation(value)
    if isinstance(value, str) and annotation is bool:
        if value.lower() not in ("true", "false", "1", "0"):
            raise ValueError(f"{value!r} is not true or false")
        return value.lower() in ("true", "1")
    return value


def make_config(name: str, preset: str, overrides: dict[str, Any] | None = None) -> Any:
    """The config of method ``name``: preset ``preset`` with ``overrides`` (field -> value, values may be
    strings as typed on a command line) applied."""
    presets = load_method(name)[1]
    if preset not in presets:
        raise DancesynthError(f"Unknown {name} preset {preset!r}; choose one of {', '.join(presets)}.")
    return config_from_dict(type(presets[preset]), {**dataclasses.asdict(presets[preset]), **(overrides or {})})


def config_from_dict(cls: type, data: dict[str, Any]) -> Any:
    """Rebuild a config dataclass from :func:`dataclasses.asdict` output (e.g. checkpoint JSON)."""
    hints = typing.get_type_hints(cls)
    fields = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - fields)
    if unknown:
        raise DancesynthError(f"{cls.__name__} has no setting {', '.join(unknown)}; "
                              f"known settings: {', '.join(sorted(fields))}.")
    try:
        return cls(**{k: _convert(v, hints[k]) for k, v in data.items()})
    except (ValueError, TypeError) as e:
        raise DancesynthError(f"Invalid {cls.__name__} setting ({e}); check the values given.") from e


def build_method(name: str, config: Any) -> Stage1Method:
    """An untrained instance of method ``name`` with ``config``."""
    return load_method(name)[0](config)
