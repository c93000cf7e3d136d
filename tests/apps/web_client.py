"""Requests to the web app's ASGI app as the page sends them, without a browser, a socket or a worker (for the
tests of :mod:`apps.web`)."""

import asyncio
import io
import json
from collections.abc import Iterable

import numpy as np
import soundfile

SERVER = ("127.0.0.1", 7860)
PAGE = {"Host": "127.0.0.1:7860", "Origin": "http://127.0.0.1:7860"}
JSON = {**PAGE, "Content-Type": "application/json"}
BOUNDARY = "dancesynthtestboundary"
FORM = {**PAGE, "Content-Type": f"multipart/form-data; boundary={BOUNDARY}"}


def call(app, method: str, path: str, headers: dict[str, str], body: bytes | Iterable[bytes] = b""):
    """(status, JSON answer, bytes of the body the app read) of one request to the ASGI ``app``. A ``body`` given
    as chunks is sent as they are asked for and without a Content-Length (chunked transfer)."""
    if isinstance(body, bytes):
        headers = {**headers, "Content-Length": str(len(body))}
        chunks: Iterable[bytes] = [body]
    else:
        chunks = body
    path, _, query = path.partition("?")
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": method, "scheme": "http",
             "path": path, "raw_path": path.encode(), "query_string": query.encode(), "root_path": "",
             "headers": [(k.lower().encode(), v.encode()) for k, v in headers.items()],
             "client": ("127.0.0.1", 50000), "server": SERVER}
    source, read, sent = iter(chunks), [0], []

    async def receive():
        chunk = next(source, None)
        if chunk is None:
            return {"type": "http.request", "body": b"", "more_body": False}
        read[0] += len(chunk)
        return {"type": "http.request", "body": chunk, "more_body": True}

    async def send(message):
        sent.append(message)

    asyncio.run(app(scope, receive, send))
    status = next(m["status"] for m in sent if m["type"] == "http.response.start")
    answer = b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")
    return status, json.loads(answer) if answer.startswith((b"{", b"[")) else None, read[0]


def form(kind: str | None, filename: str, content: bytes) -> bytes:
    """A multipart form as the page sends an upload: its kind, then the file."""
    parts = [] if kind is None else [f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="kind"\r\n\r\n{kind}\r\n']
    parts.append(f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="file"; filename="{filename}"\r\n'
                 "Content-Type: application/octet-stream\r\n\r\n")
    return "".join(parts).encode() + content + f"\r\n--{BOUNDARY}--\r\n".encode()


def wav(seconds: float = 2.0) -> bytes:
    """A WAV file of a ``seconds``-long tone at 8 kHz."""
    song = io.BytesIO()
    soundfile.write(song, 0.3 * np.sin(np.arange(int(8000 * seconds)) / 8000 * 2 * np.pi * 220), 8000, format="WAV")
    return song.getvalue()
