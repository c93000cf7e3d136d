"""Atomic output files: written under a temporary name, renamed into place only when complete."""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Iterator
from pathlib import Path

from dancesynth.core.errors import DancesynthError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``, on any error delete it.

    The temporary name keeps the extension (``name.part.ext``) so writers that choose a format by
    extension still work. An OSError (disk full, permission denied, missing folder) becomes a
    :class:`DancesynthError` naming the file.
    """
    path = Path(path)
    tmp = path.with_name(f"{path.stem}.part{path.suffix}")
    try:
        if not path.parent.is_dir():
            raise DancesynthError(f"The folder {path.parent} does not exist; create it or choose another output path.")
        yield tmp
        os.replace(tmp, path)
    except OSError as e:
        hint = "free some disk space and try again" if e.errno == errno.ENOSPC else "check the path and its permissions"
        raise DancesynthError(f"Could not write {path} ({e.strerror or e}); {hint}.") from e
    finally:
        if tmp.exists():
            tmp.unlink()
