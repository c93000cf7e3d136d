"""dancesynth: a song and a video of a person -> a video of that person dancing to the song.

The public API, one function per command (see :mod:`dancesynth.api`): :func:`dance`, :func:`generate`,
:func:`train_pose`, :func:`train_video`, :func:`extract_poses`, :func:`render`, and ``__version__``.
They are loaded on first use, so ``import dancesynth`` (and ``import dancesynth.core.x``) stays cheap.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from dancesynth.api import dance, extract_poses, generate, render, train_pose, train_video

__all__ = ["__version__", "dance", "extract_poses", "generate", "render", "train_pose", "train_video"]


def __getattr__(name: str) -> Any:
    if name == "__version__":
        from importlib.metadata import PackageNotFoundError, version

        try:
            value = version("dancesynth")
        except PackageNotFoundError:  # a source tree that was never installed
            value = "0+unknown"
        globals()[name] = value
        return value
    if name in __all__:
        from dancesynth import api

        return getattr(api, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
