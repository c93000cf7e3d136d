"""The registry of stage-1 methods: name -> method class and its named config presets.

The methods are the packages under :mod:`stage1_pose.models`; their names are found without importing them,
so listing them costs nothing, and a method is imported on first use. Each method package's ``__init__``
exports ``METHOD`` (its :class:`Stage1Method` subclass), ``CONFIG`` (its frozen config dataclass) and
``PRESETS`` (at least ``small`` and ``paper``, name -> ``CONFIG`` instance).
"""

from __future__ import annotations

import importlib
import pkgutil
from types import ModuleType
from typing import TYPE_CHECKING, Any

from dancesynth.core.config import update_config
from dancesynth.core.errors import DancesynthError
from stage1_pose import models

if TYPE_CHECKING:
    from stage1_pose.models.base import Stage1Method


def method_names() -> list[str]:
    """Registered method names (the method packages under stage1_pose/models), sorted."""
    return sorted(info.name for info in pkgutil.iter_modules(models.__path__) if info.ispkg)


def _package(name: str) -> ModuleType:
    if name not in method_names():
        raise DancesynthError(f"Unknown method {name!r}; choose one of {', '.join(method_names())}.")
    return importlib.import_module(f"{models.__name__}.{name}")


def load_method(name: str) -> tuple[type[Stage1Method], dict[str, Any]]:
    """``(method class, presets)`` of method ``name``."""
    package = _package(name)
    return package.METHOD, package.PRESETS


def config_type(name: str) -> type:
    """The config dataclass of method ``name`` (to rebuild a saved config with
    :func:`dancesynth.core.config.config_from_dict`)."""
    return _package(name).CONFIG


def make_config(name: str, preset: str, overrides: dict[str, Any] | None = None) -> Any:
    """The config of method ``name``: preset ``preset`` with ``overrides`` (field -> value, values may be
    strings as typed on a command line) applied."""
    presets = load_method(name)[1]
    if preset not in presets:
        raise DancesynthError(f"Unknown {name} preset {preset!r}; choose one of {', '.join(presets)}.")
    return update_config(presets[preset], overrides or {})


def build_method(name: str, config: Any) -> Stage1Method:
    """An untrained instance of method ``name`` with ``config``."""
    return load_method(name)[0](config)
