"""Input files checked before use; outputs checked against the inputs and each other before any work; atomic
output files: written under a unique temporary name, renamed into place only when complete."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import shutil
import stat
from collections.abc import Iterator, Mapping
from pathlib import Path

from dancesynth.core.errors import DancesynthError

PART_MARKER = ".part"
# Folders of devices and processes: a rename there replaces a device or a stream (/dev/stdout), not a file.
# /dev itself only: its subfolders hold devices (which are refused as such) or files (/dev/shm).
DEVICE_FOLDER, SYSTEM_FOLDERS = Path("/dev"), (Path("/proc"), Path("/sys"))


def temporary_sibling(path: str | os.PathLike) -> Path:
    """A fresh name beside ``path`` for writing it: ``.<stem>.<pid>-<random>.part<suffix>``.

    Unique per call, so two writers of one output never share a temporary file; in the same folder, so the
    final rename is atomic; ending in the output's extension, so writers that choose a format by it still work.
    """
    path = Path(path)
    return path.with_name(f".{path.stem}.{os.getpid()}-{secrets.token_hex(4)}{PART_MARKER}{path.suffix}")


# What temporary_sibling names: group 1 is the writing process's id.
_TEMPORARY_NAME = re.compile(r"^\..+\.(\d+)-[0-9a-f]{8}" + re.escape(PART_MARKER) + r"(?:\.[^.]*)?$")
_swept: set[str] = set()  # folders this process has already cleared of dead writers' temporary files


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (one of another user counts; so does a reused id, erring on keeping)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def remove_stale_temporaries(folder: str | os.PathLike) -> None:
    """Delete the temporary files (:func:`temporary_sibling` names) in ``folder`` whose writing process no longer
    runs, e.g. one killed with SIGKILL while rendering, which had no chance to delete its own. Only regular files
    of exactly that name pattern with a dead process id go; once per folder per process, as listing a big
    folder before every write would cost too much. Failures are ignored: this is tidying, not the write."""
    try:
        key = os.path.realpath(folder)
        if key in _swept:
            return
        _swept.add(key)
        with os.scandir(key) as entries:
            stale = [e.path for e in entries if (m := _TEMPORARY_NAME.match(e.name)) is not None
                     and e.is_file(follow_symlinks=False) and not _alive(int(m.group(1)))]
    except OSError:
        return
    for name in stale:
        with contextlib.suppress(OSError):
            os.unlink(name)


def require_file(path: str | os.PathLike, what: str = "") -> Path:
    """``path`` as a Path when it is a file, else a :class:`DancesynthError` naming it (``what``: what the file
    is, e.g. ``"Target video"``, put before the path in the sentence)."""
    path = Path(path)
    if not path.is_file():
        raise DancesynthError(f"{what + ' ' if what else ''}{path} does not exist; check the path.")
    return path


def _mode(path: str | os.PathLike) -> int:
    """The file type and permission bits of ``path`` (links followed); 0 when nothing is there."""
    try:
        return os.stat(path).st_mode
    except OSError:
        return 0


def _special_kind(mode: int) -> str | None:
    """"a device", "a named pipe" or "a socket" for a ``mode`` of that type, None for any other."""
    for test, kind in ((stat.S_ISCHR, "a device"), (stat.S_ISBLK, "a device"), (stat.S_ISFIFO, "a named pipe"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return None


def _system_folder(path: str | os.PathLike) -> str | None:
    """The end of the sentence "``path`` is ..." when ``path`` is a name in ``/dev`` (not its subfolders),
    ``/proc`` or ``/sys``; None elsewhere."""
    folder = _entry(path).parent
    system = next((f for f in SYSTEM_FOLDERS if folder.is_relative_to(f)), DEVICE_FOLDER if folder == DEVICE_FOLDER
                  else None)
    return f"in {system}, a folder of the system's devices and processes" if system is not None else None


def special_file(path: str | os.PathLike) -> str | None:
    """Why writing a file at ``path`` would replace something that is not a file, as the end of the sentence
    "``path`` is ...": an existing device, named pipe or socket (links followed), or any name in ``/dev`` (not
    its subfolders), ``/proc`` or ``/sys``; None for a regular file, a folder or a new name elsewhere."""
    kind = _special_kind(_mode(path))
    return f"{kind}, not a regular file" if kind is not None else _system_folder(path)


def not_a_folder(path: str | os.PathLike) -> str | None:
    """Why ``path`` cannot be a folder to write into, as the end of the sentence "``path`` is ...": an existing
    file, device, named pipe or socket (links followed), or a name in ``/dev``, ``/proc`` or ``/sys`` (see
    :func:`special_file`); None for a folder or a new name elsewhere."""
    mode = _mode(path)
    if mode and not stat.S_ISDIR(mode):
        return f"{_special_kind(mode) or 'a file'}, not a folder"
    return _system_folder(path)


def _entry(path: str | os.PathLike) -> Path:
    """The folder entry a rename onto ``path`` replaces: its folder with links resolved, and its own name."""
    path = Path(os.path.abspath(path))
    return Path(os.path.realpath(path.parent)) / path.name


def _same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether ``a`` and ``b`` name one file: the same name once links are resolved, or (both existing) the same
    file through another link or a hard link."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


# What dancesynth.core.media.VideoWriter writes (H.264 in an MP4 container) and the names that say so.
VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov")


def misnamed_video(path: str | os.PathLike) -> bool:
    """True when a video output's name says another format than the MP4 written (``.webm``, ``.gif``, ``.avi``,
    none): players would refuse it."""
    return Path(path).suffix.lower() not in VIDEO_SUFFIXES


def check_video_names(videos: Mapping[str, str | os.PathLike | None]) -> None:
    """Refuse a video output (``videos``: what each is, e.g. ``"dance video"``, to its path; None: not given) that
    :func:`misnamed_video` refuses, with a :class:`DancesynthError` naming it."""
    for what, path in videos.items():
        if path is not None and misnamed_video(path):
            raise DancesynthError(f"The {what} {path} would hold an MP4 video; give it a name ending in .mp4.")


def check_outputs(outputs: Mapping[str, str | os.PathLike | None],
                  inputs: Mapping[str, str | os.PathLike | None] | None = None,
                  folders: Mapping[str, str | os.PathLike | None] | None = None) -> None:
    """Refuse, before any work, outputs that would destroy what the command reads, each other or a device.

    ``outputs`` (files), ``inputs`` and ``folders`` (output folders: run folders, datasets, reports) map what each
    path is (e.g. ``"dance video"``, ``"song"``, ``"run folder"``) to the path (None: not given). A
    :class:`DancesynthError` names the output file when it is an input file or folder, an existing file inside an
    input folder, another output, or not a place for a file (:func:`special_file`); it names the output folder
    when it is an input, holds an input folder, or is no folder (:func:`not_a_folder`). An existing folder is
    accepted as it is: a run folder is resumed in place.
    """
    given = {what: path for what, path in outputs.items() if path is not None}
    sources = {what: path for what, path in (inputs or {}).items() if path is not None}
    for what, folder in (folders or {}).items():
        if folder is not None:
            _check_output_folder(what, folder, sources)
    for index, (what, path) in enumerate(given.items()):
        kind = special_file(path)
        if kind is not None:
            raise DancesynthError(f"The {what} {path} is {kind}; give the path of a file to write instead.")
        for source_what, source in sources.items():
            if _same_file(path, source):
                relation = "the"
            elif (os.path.isdir(source) and os.path.lexists(path)
                  and _entry(path).is_relative_to(os.path.realpath(source))):
                relation = "a file of the"
            else:
                continue
            raise DancesynthError(f"The {what} {path} is {relation} {source_what} {source}; choose another output "
                                  f"path so that the {source_what} is not overwritten.")
        for other_what, other in list(given.items())[:index]:
            if _same_file(path, other):
                raise DancesynthError(f"The {what} {path} is also the {other_what} {other}; give each output its "
                                      "own path.")


def _check_output_folder(what: str, folder: str | os.PathLike,
                         sources: Mapping[str, str | os.PathLike]) -> None:
    """Refuse the output folder ``folder`` (see :func:`check_outputs`) when it is no folder, is one of ``sources``
    or holds an input folder: its writes would mix with, or replace, what the command reads. An input file inside
    it is fine (e.g. ``--poses RUN/poses.npz --out RUN``): the command writes its own names."""
    kind = not_a_folder(folder)
    if kind is not None:
        raise DancesynthError(f"The {what} {folder} is {kind}; give the path of a folder to write into instead.")
    for source_what, source in sources.items():
        if _same_file(folder, source):
            relation = "is the"
        elif os.path.isdir(source) and Path(os.path.realpath(source)).is_relative_to(os.path.realpath(folder)):
            relation = "holds the"
        else:
            continue
        raise DancesynthError(f"The {what} {folder} {relation} {source_what} {source}; choose another output folder "
                              f"so that the {source_what} is not overwritten.")


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
    ``mkdir``) would give it. A device, named pipe or socket at ``path`` is refused, not replaced.

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
    kind = special_file(path)
    if kind is not None:
        raise DancesynthError(f"{path} is {kind}; give the path of a file to write instead.")
    remove_stale_temporaries(path.parent)
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
