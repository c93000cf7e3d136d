"""Input files checked before use; atomic output files: written under a unique temporary name, renamed into
place only when complete."""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
from collections.abc import Iterator
from pathlib import Path

from dancesynth.core.errors import DancesynthError

PART_MARKER = ".part"


def temporary_sibling(path: str | os.PathLike) -> Path:
    """A fresh name beside ``path`` for writing it: ``.<stem>.<pid>-<random>.part<suffix>``.

    Unique per call, so two writers of one output never share a temporary file; in the same folder, so the
    final rename is atomic; ending in the output's extension, so writers that choose a format by it still work.
    """
    path = Path(path)
    return path.with_name(f".{path.stem}.{os.getpid()}-{secrets.token_hex(4)}{PART_MARKER}{path.suffix}")


def require_file(path: str | os.PathLike, what: str = "") -> Path:
    """``path`` as a Path when it is a file, else a :class:`DancesynthError` naming it (``what``: what the file
    is, e.g. ``"Target video"``, put before the path in the sentence)."""
    path = Path(path)
    if not path.is_file():
        raise DancesynthError(f"{what + ' ' if what else ''}{path} does not exist; check the path.")
    return path


def os_error_sentence(error: OSError, path: str | os.PathLike | None = None) -> str:
    """One sentence for a failed file operation: what failed, why (disk full, read-only, permission) and what to do."""
    target = path if path is not None else error.filename
    writing = path is not None or error.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS)
    what = f"Could not {'write' if writing else 'access'} {target}" if target is not None else "A file operation failed"
    reason = error.strerror or str(error) or type(error).__name__
    if error.errno in (errno.ENOSPC, errno.EDQUOT):
        hint = "free some disk space and try again"
    elif error.errno == errno.EROFS:
        hint = "the file system is read-only, choose an output on a writable disk"
    elif error.errno in (errno.EACCES, errno.EPERM):
        hint = "choose a folder you may write to or fix its permissions"
    else:
        hint = "check the path and its permissions"
    return f"{what} ({reason}); {hint}."


def _remove(path: Path) -> None:
    """Delete a leftover temporary file or folder; a failure here (e.g. a read-only disk) must not hide the cause."""
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


def _umask() -> int:
    mask = os.umask(0o022)  # reading the umask means setting it; it is put back at once
    os.umask(mask)
    return mask


def _set_plain_modes(tmp: Path, path: Path, folder: bool) -> None:
    """Give ``tmp`` the permissions writing ``path`` directly would: an existing file keeps its own, anything new
    gets 0666 (folders 0777) less the umask. Some writers (safetensors, tempfile) create their files 0600."""
    mask = _umask()
    if not folder:
        mode = path.stat().st_mode & 0o7777 if path.is_file() else 0o666 & ~mask
        os.chmod(tmp, mode)
        return
    os.chmod(tmp, 0o777 & ~mask)
    for dirpath, dirnames, filenames in os.walk(tmp):
        for name in dirnames:
            os.chmod(os.path.join(dirpath, name), 0o777 & ~mask)
        for name in filenames:
            if not os.path.islink(os.path.join(dirpath, name)):
                os.chmod(os.path.join(dirpath, name), 0o666 & ~mask)


def _replace_folder(tmp: Path, path: Path) -> None:
    """Move the finished folder ``tmp`` onto ``path``; an existing folder there is moved aside first and deleted."""
    old = temporary_sibling(path)
    try:
        if path.is_dir():
            os.replace(path, old)
        os.replace(tmp, path)
    finally:
        _remove(old)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, folder: bool = False) -> Iterator[Path]:
    """Yield a fresh temporary path beside ``path`` (see :func:`temporary_sibling`); on success rename it to
    ``path``, on any error or interruption delete it. The output gets the permissions a plain ``open()`` (or
    ``mkdir``) would give it.

    With ``folder`` the caller creates a folder at the temporary path; it replaces an existing folder ``path``.
    Otherwise ``path`` must not be a folder. Two concurrent writers each finish with a complete output; the last
    rename wins. An OSError (disk full, read-only, permission denied) becomes a :class:`DancesynthError` naming
    the file.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise DancesynthError(f"Could not write {path}: the folder {path.parent} does not exist; "
                              "create it or choose another output path.")
    if path.is_dir() and not folder:
        raise DancesynthError(f"{path} is a folder; give a file name for the output instead.")
    tmp = temporary_sibling(path)
    try:
        yield tmp
        _set_plain_modes(tmp, path, folder)
        if folder:
            _replace_folder(tmp, path)
        else:
            os.replace(tmp, path)
    except OSError as e:
        raise DancesynthError(os_error_sentence(e, path)) from e
    finally:
        _remove(tmp)
