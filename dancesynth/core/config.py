"""One round trip for every config dataclass: typed dict <-> dataclass, ``--set key=value`` and TOML files.

Values arriving from JSON, TOML or a command line are converted to each field's annotated type: lists and
comma-separated strings become tuples, strings are parsed as int / float / bool, ``none`` sets an optional
field to None, and a dict fills a nested config dataclass. Unknown keys are an error naming them.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tomllib
import types
import typing
from typing import Any, TypeVar

from dancesynth.core.errors import DancesynthError
from dancesynth.core.fileio import require_file

C = TypeVar("C")

_TRUE, _FALSE = ("true", "1", "yes"), ("false", "0", "no")


def _convert(value: Any, annotation: Any, name: str) -> Any:
    """One JSON / TOML / command-line value -> the type ``annotation`` of field ``name``; ValueError if it
    does not fit."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        unset = value is None or (isinstance(value, str) and value.strip().lower() in ("none", "null"))
        if unset and type(None) in args:
            return None
        for option in (a for a in args if a is not type(None)):
            try:
                return _convert(value, option, name)
            except ValueError:
                continue
        raise ValueError(f"{name}={value!r} is not {annotation}")
    if origin is tuple:
        if isinstance(value, str):
            value = [v for v in value.strip().strip("()[]").split(",") if v.strip()]
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{name}={value!r} is not a list")
        items = args[:1] * len(value) if len(args) == 2 and args[1] is Ellipsis else args
        if len(items) != len(value):
            raise ValueError(f"{name} needs {len(items)} values, got {len(value)}")
        return tuple(_convert(v, a, name) for v, a in zip(value, items))
    if dataclasses.is_dataclass(annotation):
        if isinstance(value, annotation):
            return value
        if not isinstance(value, dict):
            raise ValueError(f"{name} is a group of settings, not {value!r}")
        return config_from_dict(annotation, value)
    if annotation is bool:
        if isinstance(value, str) and value.strip().lower() in _TRUE + _FALSE:
            return value.strip().lower() in _TRUE
        if isinstance(value, bool) or (isinstance(value, int) and value in (0, 1)):
            return bool(value)
        raise ValueError(f"{name}={value!r} is not true or false")
    if annotation in (int, float):
        kind = "a whole number" if annotation is int else "a number"
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise ValueError(f"{name}={value!r} is not {kind}")
        if annotation is int and isinstance(value, float):
            if not value.is_integer():
                raise ValueError(f"{name}={value!r} is not {kind}")
            return int(value)
        try:
            return annotation(value)
        except ValueError:
            raise ValueError(f"{name}={value!r} is not {kind}") from None
    if annotation is str:
        if not isinstance(value, str):
            raise ValueError(f"{name}={value!r} is not text")
        return value
    if isinstance(annotation, type) and not isinstance(value, annotation):
        return annotation(value)
    return value


def config_from_dict(cls: type[C], data: dict[str, Any]) -> C:
    """An instance of config dataclass ``cls`` from ``data`` (e.g. :func:`config_to_dict` output, a checkpoint's
    JSON or a TOML file); missing fields take their defaults. Raises DancesynthError on an unknown key or a
    value that does not fit its field."""
    hints = typing.get_type_hints(cls)
    known = [f.name for f in dataclasses.fields(cls) if f.init]
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise DancesynthError(f"{cls.__name__} has no setting {', '.join(unknown)}; "
                              f"known settings: {', '.join(sorted(known))}.")
    try:
        return cls(**{k: _convert(v, hints[k], k) for k, v in data.items()})
    except (ValueError, TypeError) as e:
        raise DancesynthError(f"Invalid {cls.__name__} setting ({e}); check the value given.") from e


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return config_to_dict(value)
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    return value


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """Config dataclass -> JSON-able dict (tuples become lists, nested configs dicts);
    :func:`config_from_dict` inverts it."""
    return {f.name: _plain(getattr(cfg, f.name)) for f in dataclasses.fields(cfg) if f.init}


def _merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``changes`` applied; a dict change into a dict value merges instead of replacing."""
    out = dict(base)
    for key, value in changes.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def update_config(cfg: C, changes: dict[str, Any]) -> C:
    """A copy of ``cfg`` with the fields in ``changes`` replaced (values converted as in
    :func:`config_from_dict`; a dict for a nested config changes only the keys it names)."""
    return config_from_dict(type(cfg), _merge(config_to_dict(cfg), changes))


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["key=value", "group.key=value", ...]`` (``--set`` arguments) -> nested dict of the string values."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        path = [part.strip() for part in key.split(".")]
        if not sep or not all(path):
            raise DancesynthError(f"--set {item!r} is not FIELD=VALUE; write e.g. --set lstm_hidden=256.")
        change: Any = value.strip()
        for part in reversed(path):
            change = {part: change}
        out = _merge(out, change)
    return out


def apply_overrides(cfg: C, items: list[str]) -> C:
    """A copy of ``cfg`` with ``--set``-style ``key=value`` items applied (``group.key=value`` for a nested
    config); raises DancesynthError on a malformed item, an unknown key or a value that does not fit."""
    return update_config(cfg, parse_overrides(items))


def load_config_file(path: str | os.PathLike) -> dict[str, Any]:
    """The settings in a TOML file (or, for a ``.json`` name, a JSON object) as a dict, for
    :func:`update_config` / :func:`config_from_dict`."""
    path = require_file(path, "Config file")
    try:
        if path.suffix.lower() == ".json":
            data = json.loads(path.read_text(encoding="utf-8"))
        else:
            with path.open("rb") as f:
                data = tomllib.load(f)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DancesynthError(f"Config file {path} cannot be read ({e}); fix it or write key = value lines.") from e
    if not isinstance(data, dict):
        raise DancesynthError(f"Config file {path} does not hold a table of settings; write key = value lines.")
    return data


def _toml_value(value: Any) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    # JSON's bool, number and string spellings are valid TOML for these values.
    return json.dumps(value)


def _toml_lines(data: dict[str, Any], table: str) -> list[str]:
    lines = [f"[{table}]"] if table else []
    for key, value in data.items():
        if not isinstance(value, dict):
            lines.append(f"# {key} is not set" if value is None else f"{key} = {_toml_value(value)}")
    for key, value in data.items():
        if isinstance(value, dict):
            lines += ["", *_toml_lines(value, f"{table}.{key}" if table else key)]
    return lines


def config_to_toml(cfg: Any) -> str:
    """Config dataclass -> TOML text for :func:`load_config_file`; a nested config becomes a table. TOML has
    no null, so an unset (None) field is only a comment and reads back as unset only over a base where it is."""
    return "\n".join(_toml_lines(config_to_dict(cfg), "")) + "\n"


def format_config(cfg: Any, fmt: str = "toml") -> str:
    """``cfg`` as ``toml`` or ``json`` text (both readable by :func:`load_config_file`)."""
    if fmt == "json":
        return json.dumps(config_to_dict(cfg), indent=2) + "\n"
    if fmt == "toml":
        return config_to_toml(cfg)
    raise DancesynthError(f"Unknown config format {fmt!r}; choose toml or json.")
