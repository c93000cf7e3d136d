"""The web app answers its own page only: forged Host (DNS rebinding), Origin (another site's form or script) and
content types, sent to the ASGI app directly (no browser, no socket, no worker)."""

import asyncio
import json

import pytest

from apps.web.server import create_app

SERVER = ("127.0.0.1", 7860)
PAGE = "http://127.0.0.1:7860"
JOB = json.dumps({"kind": "demo", "minutes": 2}).encode()
JSON = {"Content-Type": "application/json"}


async def _call(app, method: str, path: str, headers: dict[str, str], body: bytes, server: tuple[str, int]):
    """(status, JSON answer or None) of one HTTP request to the ASGI ``app`` over a connection to ``server``."""
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": method, "scheme": "http",
             "path": path, "raw_path": path.encode(), "query_string": b"", "root_path": "",
             "headers": [(k.lower().encode(), v.encode()) for k, v in headers.items()],
             "client": ("127.0.0.1", 50000), "server": server}
    messages = [{"type": "http.request", "body": body, "more_body": False}]
    sent = []

    async def receive():
        return messages.pop(0) if messages else {"type": "http.disconnect"}

    async def send(message):
        sent.append(message)

    await app(scope, receive, send)
    status = next(m["status"] for m in sent if m["type"] == "http.response.start")
    answer = b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")
    is_json = answer.startswith((b"{", b"["))
    return status, json.loads(answer) if is_json else None


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    root = tmp_path_factory.mktemp("web_origin")
    app = create_app(root / "data", root / "cache", device="cpu")
    yield app
    app.state.web.start_cleanup.join(60)


def request(app, method: str, path: str, headers: dict[str, str] | None = None, body: bytes = b"",
            host: str | None = "127.0.0.1:7860", server: tuple[str, int] = SERVER):
    """``_call`` with a ``Host`` header (None: none) besides ``headers``."""
    headers = {**({"Host": host} if host is not None else {}), **(headers or {})}
    return asyncio.run(_call(app, method, path, headers, body, server))


def _jobs(app) -> int:
    return len(app.state.web.jobs.jobs())


@pytest.mark.parametrize("host", ["evil.example:7860", "evil.example", "127.0.0.1:7861", "127.0.0.1",
                                  "127.0.0.1:7860@evil.example", "evil.example:7860/", None])
@pytest.mark.parametrize("path", ["/", "/api/config", "/api/jobs", "/api/jobs/x/files/dance.mp4", "/static/app.js"])
def test_a_foreign_host_is_refused_whatever_it_asks(app, host, path):
    status, answer = request(app, "GET", path, host=host)
    assert status == 403
    assert answer["error"].startswith("This server answers requests for 127.0.0.1:7860 only")
    assert answer["error"].endswith("open the page at http://127.0.0.1:7860/.")


@pytest.mark.parametrize("host", ["127.0.0.1:7860", "localhost:7860", "LOCALHOST:7860", "[::1]:7860"])
def test_the_loopback_answers_by_its_names(app, host):
    status, answer = request(app, "GET", "/api/config", host=host)
    assert status == 200 and answer["device"] == "cpu"


def test_a_server_on_another_address_answers_that_address_and_its_own_name_only(tmp_path):
    app = create_app(tmp_path / "data", tmp_path / "cache", device="cpu", host="studio.lan")
    lan = ("192.168.1.5", 7860)
    for host in ("192.168.1.5:7860", "studio.lan:7860"):
        assert request(app, "GET", "/api/config", host=host, server=lan)[0] == 200
    for host in ("localhost:7860", "127.0.0.1:7860", "evil.example:7860"):
        status, answer = request(app, "GET", "/api/config", host=host, server=lan)
        assert status == 403 and "answers requests for 192.168.1.5:7860 only" in answer["error"]
    app.state.web.start_cleanup.join(60)


@pytest.mark.parametrize("headers, says", [
    ({"Origin": "http://evil.example"}, "comes from 'http://evil.example'"),
    ({"Origin": "http://evil.example:7860"}, "comes from"),
    ({"Origin": "http://127.0.0.1:7861"}, "comes from"),
    ({"Origin": "https://127.0.0.1:7860"}, "comes from"),
    ({"Origin": "null"}, "comes from 'null'"),
    ({"Referer": "http://evil.example/page.html"}, "comes from 'http://evil.example/page.html'"),
    ({"Origin": "http://evil.example", "Referer": f"{PAGE}/"}, "comes from 'http://evil.example'"),
    ({}, "names no page"),
])
@pytest.mark.parametrize("content_type", ["text/plain", "application/json"])
def test_a_job_request_from_another_page_is_refused_and_starts_nothing(app, headers, says, content_type):
    before = _jobs(app)
    status, answer = request(app, "POST", "/api/jobs", {"Content-Type": content_type, **headers}, JOB)
    assert status == 403 and answer["error"].startswith("Only this server's own page may change something here, "
                                                        f"and this request {says}")
    assert answer["error"].endswith("; use the page at http://127.0.0.1:7860/.")
    assert _jobs(app) == before


@pytest.mark.parametrize("path", ["/api/uploads", "/api/jobs/x/cancel"])
def test_uploads_and_cancels_from_another_page_are_refused(app, path):
    headers = {"Origin": "http://evil.example", "Content-Type": "multipart/form-data; boundary=x"}
    status, answer = request(app, "POST", path, headers, b"--x--\r\n")
    assert status == 403 and "comes from 'http://evil.example'" in answer["error"]
    assert not (app.state.web.data / "uploads").exists() or not any((app.state.web.data / "uploads").iterdir())


@pytest.mark.parametrize("content_type", ["text/plain", "application/x-www-form-urlencoded",
                                          "multipart/form-data; boundary=x", None])
def test_a_job_request_that_is_not_typed_json_is_415(app, content_type):
    before = _jobs(app)
    headers = {"Origin": PAGE, **({"Content-Type": content_type} if content_type else {})}
    status, answer = request(app, "POST", "/api/jobs", headers, JOB)
    assert status == 415 and answer["error"].startswith("A job request is JSON, not ")
    assert answer["error"].endswith("send it with Content-Type: application/json, as the page does.")
    assert _jobs(app) == before


@pytest.mark.parametrize("headers", [{"Origin": PAGE}, {"Origin": "http://localhost:7860"},
                                     {"Referer": f"{PAGE}/#dance"}])
def test_the_pages_own_requests_still_work(app, headers):
    assert request(app, "GET", "/")[0] == 200
    before = _jobs(app)
    status, job = request(app, "POST", "/api/jobs", {**JSON, "Content-Type": "application/json; charset=utf-8",
                                                     **headers}, JOB)
    assert status == 200 and job["kind"] == "demo" and job["state"] == "queued"
    assert _jobs(app) == before + 1
    status, cancelled = request(app, "POST", f"/api/jobs/{job['id']}/cancel", {**JSON, **headers})
    assert status == 200 and cancelled["state"] == "cancelled"
    # Bad input from the page still gets its 400 sentence.
    status, answer = request(app, "POST", "/api/jobs", {**JSON, **headers}, b"[1]")
    assert status == 400 and answer["error"].startswith("A job request is a JSON object")


def test_the_page_sends_its_json_typed_and_its_uploads_as_forms():
    from apps.web.server import STATIC

    script = (STATIC / "app.js").read_text()
    assert 'method: "POST", headers: { "Content-Type": "application/json" }' in script
    assert "new FormData()" in script and 'xhr.open("POST", "/api/uploads")' in script
