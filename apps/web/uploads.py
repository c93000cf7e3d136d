"""Uploads as they stream in: the page's multipart form (a ``kind`` field and one ``file``) read part by part, the
file written straight into its upload folder under a name the server chooses and refused the moment it passes the
server's limit, so an upload over the limit, its length declared or not (chunked), leaves nothing on disk: no
temporary file anywhere, and the caller removes the folder.

```
DATA/uploads/<id>/media.<ext>    the uploaded file (<ext>: the user's extension reduced to safe characters)
DATA/uploads/<id>/upload.json    id, kind, name (the user's file name: shown, and said in messages), file,
                                 duration (seconds), size (bytes)
```

The user's file name never becomes a path, so no upload (one named ``upload.json`` say) can replace its metadata.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

from python_multipart.exceptions import FormParserError
from python_multipart.multipart import MultipartParser, parse_options_header
from starlette.concurrency import run_in_threadpool

from dancesynth.core.errors import DancesynthError

if TYPE_CHECKING:
    from starlette.requests import Request

UPLOADS = "uploads"
UPLOAD_META = "upload.json"
UPLOAD_STEM = "media"
# The form's fields besides the file: their names and at most this many bytes each, and all of them together with
# the parts' headers and boundaries at most FORM_BYTES on top of the file.
FIELDS = ("kind",)
FIELD_BYTES = 64
FORM_BYTES = 64 * 1024
FILE_FIELD = "file"
# An upload's path inside a message: DATA/uploads/<id>/<file> (file names as display_name and stored_name make them).
UPLOAD_PATH = r"/(?P<id>[0-9a-f]+)/(?P<file>[A-Za-z0-9_-]+(?:\.[A-Za-z0-9_-]+)?)"


class UploadTooLarge(DancesynthError):
    """An upload over the server's size limit (HTTP 413 rather than 400)."""

    status = 413


def too_big(filename: str | None, size: int | None, limit_mb: float) -> UploadTooLarge:
    """The sentence refusing the file ``filename`` (the user's name for it, None: not known) of ``size`` bytes
    (None: not known, the upload was stopped at the limit)."""
    name = display_name(filename) if filename else "The file"
    size_text = f"is {size / 2**20:.0f} MB" if size is not None else "is larger than that"
    return UploadTooLarge(f"{name} {size_text}, over this server's upload limit of {limit_mb:g} MB; use a shorter "
                          "file or start the server with a larger --max-upload-mb.")


def _clean(text: str, length: int) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "_", text)[:length].strip("_")


def display_name(name: str) -> str:
    """The user's file name reduced to characters safe to show and to say in a message (its extension kept)."""
    stem, dot, ext = Path(name or "upload").name.rpartition(".")
    stem, ext = (stem, ext) if dot else (ext, "")
    return (_clean(stem, 60) or "upload") + (f".{_clean(ext, 10)}" if _clean(ext, 10) else "")


def stored_name(name: str) -> str:
    """The name the server stores the upload ``name`` under: ``media`` with the user's extension (decoders and
    players go by it), so it never meets the folder's metadata."""
    _, dot, ext = display_name(name).partition(".")
    return UPLOAD_STEM + dot + ext


def user_message(message: str, data: Path) -> str:
    """A message without the data folder's upload paths: each one (``DATA/uploads/<id>/media.mp3``) reads as the
    user's name for it (its ``upload.json``'s ``name``; the stored file's name while it has none yet)."""

    def name(match: re.Match) -> str:
        try:
            meta = json.loads((data / UPLOADS / match["id"] / UPLOAD_META).read_text())
            return str(meta["name"]) if isinstance(meta, dict) and "name" in meta else match["file"]
        except (OSError, ValueError):
            return match["file"]

    return re.sub(re.escape(str(data / UPLOADS)) + UPLOAD_PATH, name, message)


@dataclasses.dataclass
class UploadForm:
    """What :func:`receive_form` read: the text fields, the user's name of the file, where it went and its size
    (bytes)."""

    fields: dict[str, str]
    filename: str
    path: Path
    size: int


class _FormReader:
    """python_multipart's callbacks: text fields kept (bounded), the one file part opened in ``folder`` and its
    bytes queued for the caller to write."""

    def __init__(self, folder: Path, limit_mb: float) -> None:
        self.folder, self.limit_mb, self.limit = folder, limit_mb, int(limit_mb * 2**20)
        self.fields: dict[str, str] = {}
        self.filename: str | None = None
        self.path: Path | None = None
        self.file: BinaryIO | None = None
        self.size = 0
        self.pending: list[bytes] = []
        self.ended = False
        self._header = [b"", b""]
        self._disposition = b""
        self._field: str | None = None  # the text field being read (None: the file part)
        self._value = b""

    def callbacks(self) -> dict:
        return {"on_part_begin": self._part_begin, "on_header_field": self._header_field,
                "on_header_value": self._header_value, "on_header_end": self._header_end,
                "on_headers_finished": self._headers_finished, "on_part_data": self._part_data,
                "on_part_end": self._part_end, "on_end": self._end}

    def _part_begin(self) -> None:
        self._disposition, self._field, self._value = b"", None, b""

    def _header_field(self, data: bytes, start: int, end: int) -> None:
        self._header[0] += data[start:end]

    def _header_value(self, data: bytes, start: int, end: int) -> None:
        self._header[1] += data[start:end]

    def _header_end(self) -> None:
        if self._header[0].lower() == b"content-disposition":
            self._disposition = self._header[1]
        self._header = [b"", b""]

    def _headers_finished(self) -> None:
        _, options = parse_options_header(self._disposition)
        field = options.get(b"name", b"").decode("utf-8", "replace")
        if b"filename" not in options:
            if field not in FIELDS or field in self.fields:
                raise DancesynthError(f"The upload form has a field {field[:40]!r} it should not have; an upload "
                                      f"is the fields {', '.join(FIELDS)} and {FILE_FIELD}, as the page sends.")
            self._field = field
            return
        if field != FILE_FIELD or self.filename is not None:
            raise DancesynthError(f"An upload is one file, in the form's field {FILE_FIELD!r}; upload one file at "
                                  "a time, as the page does.")
        self.filename = options[b"filename"].decode("utf-8", "replace")
        self.path = self.folder / stored_name(self.filename)
        self.file = open(self.path, "xb")

    def _part_data(self, data: bytes, start: int, end: int) -> None:
        if self._field is not None:
            self._value += data[start:end]
            if len(self._value) > FIELD_BYTES:
                raise DancesynthError(f"The upload form's field {self._field!r} is longer than {FIELD_BYTES} bytes; "
                                      "upload the file from the page.")
            return
        self.size += end - start
        if self.size > self.limit:
            raise too_big(self.filename, None, self.limit_mb)
        self.pending.append(data[start:end])

    def _part_end(self) -> None:
        if self._field is not None:
            self.fields[self._field] = self._value.decode("utf-8", "replace")

    def _end(self) -> None:
        self.ended = True


async def receive_form(request: Request, folder: Path, limit_mb: float) -> UploadForm:
    """Read the upload form of ``request`` as it streams, writing its file into ``folder`` (which the caller
    removes should this raise): :class:`UploadTooLarge` as soon as the file passes ``limit_mb`` MB or the whole
    body passes that and :data:`FORM_BYTES`; a :class:`DancesynthError` for a body that is not such a form."""
    content_type, options = parse_options_header(request.headers.get("content-type"))
    if content_type != b"multipart/form-data" or not options.get(b"boundary"):
        raise DancesynthError("An upload is a multipart form (the fields kind and file), as the page sends; "
                              "upload the file from the page.")
    reader = _FormReader(folder, limit_mb)
    parser = MultipartParser(options[b"boundary"], reader.callbacks())
    received = 0
    try:
        async for chunk in request.stream():
            received += len(chunk)
            if received > reader.limit + FORM_BYTES:
                raise too_big(reader.filename or request.headers.get("x-file-name"), None, limit_mb)
            parser.write(chunk)
            if reader.pending:
                await run_in_threadpool(reader.file.write, b"".join(reader.pending))
                reader.pending.clear()
        parser.finalize()
    except FormParserError as e:
        raise DancesynthError("The upload is not a well-formed multipart form; upload the file again from the "
                              "page.") from e
    finally:
        if reader.file is not None:
            reader.file.close()
    if not reader.ended:
        raise DancesynthError("The upload ended before its last byte; upload the file again.")
    if reader.path is None:
        raise DancesynthError(f"The upload has no file (the form's field {FILE_FIELD!r}); choose a file and upload "
                              "it again.")
    return UploadForm(reader.fields, reader.filename, reader.path, reader.size)
