"""The dashboard's server on bad requests and bad addresses: clean answers, clean errors, no tracebacks.

The server is the real one (uvicorn with the dashboard's app, on a free port of 127.0.0.1, in a thread of
the test); the requests are written byte by byte on a socket, as a broken or hostile client would.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from pathlib import Path

import pytest
import uvicorn

from rivercal.dashboard.app import MAX_BODY, create_app
from tests.cli import rivercal
from tests.dashboard_store import build_store


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_store(tmp_path_factory.mktemp("dash") / "run.sqlite", 3)


@pytest.fixture
def server(store: Path):
    config = uvicorn.Config(create_app(store), host="127.0.0.1", port=0, log_level="warning", access_log=False)
    srv = uvicorn.Server(config)
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not srv.started and time.monotonic() < deadline:
        time.sleep(0.05)
    assert srv.started
    yield srv.servers[0].sockets[0].getsockname()[1]
    srv.should_exit = True
    thread.join(timeout=30)


def _ask(port: int, raw: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(raw)
        answer = b""
        while chunk := sock.recv(65536):
            answer += chunk
    return answer


@pytest.mark.parametrize("method", ["GET", "POST"])
def test_a_broken_chunked_body_gets_400_and_no_traceback(server: int, method: str, caplog) -> None:
    with caplog.at_level(logging.WARNING):
        for _ in range(5):  # the server's 400 and the page's answer raced: try it a few times
            answer = _ask(server, f"{method} / HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n"
                                  "ZZZ\r\nabc\r\n0\r\n\r\n".encode())
            assert answer.startswith(b"HTTP/1.1 400 ")
        time.sleep(0.2)
    assert "Exception in ASGI application" not in caplog.text and "Traceback" not in caplog.text
    assert "Invalid HTTP request received" in caplog.text  # the server's own one-line warning


def test_a_request_with_a_body_is_still_answered(server: int) -> None:
    answer = _ask(server, b"GET /api/version HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\nConnection: close\r\n\r\n"
                          b"hello")
    assert answer.startswith(b"HTTP/1.1 200 ") and b'"run":"dash"' in answer
    for method in ("POST", "PUT", "DELETE", "PATCH", "OPTIONS"):
        answer = _ask(server, f"{method} /cycles HTTP/1.1\r\nHost: x\r\nContent-Length: 8\r\nConnection: close\r\n"
                              "\r\ncycle=99".encode())
        assert answer.startswith(b"HTTP/1.1 405 ") and b"allow: GET, HEAD" in answer, method
    big = MAX_BODY + 10
    answer = _ask(server, f"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: {big}\r\nConnection: close\r\n\r\n".encode()
                  + b"x" * big)
    assert answer.startswith(b"HTTP/1.1 413 ")


def test_an_address_that_is_not_this_machines_is_a_bad_option(store: Path) -> None:
    run = rivercal("dashboard", "--db", str(store), "--host", "256.1.1.1")
    assert run.returncode == 2, run.stderr
    assert "--host 256.1.1.1: not an address" in run.stderr and "internal error" not in run.stderr


def test_a_port_in_use_is_a_bad_option(store: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        run = rivercal("dashboard", "--db", str(store), "--port", str(port))
    assert run.returncode == 2, run.stderr
    assert f"--port {port}: already in use on 127.0.0.1; give another port" in run.stderr


def _get(port: int, path: str, **headers: str) -> tuple[int, dict[str, str], bytes]:
    import http.client

    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        conn.request("GET", path, headers=headers)
        answer = conn.getresponse()
        return answer.status, {k.lower(): v for k, v in answer.getheaders()}, answer.read()
    finally:
        conn.close()


def test_plotly_is_sent_compressed_under_an_address_a_browser_may_keep(server: int) -> None:
    import gzip
    import importlib.resources
    import re

    plain = (importlib.resources.files("plotly") / "package_data" / "plotly.min.js").read_bytes()
    status, _, page = _get(server, "/map")
    assert status == 200
    address = re.search(rb'src="(/static/plotly\.min\.js\?v=[0-9a-f]{16})"', page).group(1).decode()
    status, headers, body = _get(server, address, **{"Accept-Encoding": "gzip, deflate, br"})
    assert status == 200 and headers["content-encoding"] == "gzip" and headers["vary"] == "accept-encoding"
    assert gzip.decompress(body) == plain
    assert len(body) < 0.4 * len(plain)  # 4.8 MB → about 1.5 MB
    assert headers["cache-control"] == "public, max-age=31536000, immutable"
    # a browser that asks again with the tag gets 304 and no body; one that takes no gzip gets the file itself
    status, _, body = _get(server, address, **{"If-None-Match": headers["etag"], "Accept-Encoding": "gzip"})
    assert status == 304 and body == b""
    status, headers, body = _get(server, address, **{"Accept-Encoding": "gzip;q=0"})
    assert status == 200 and "content-encoding" not in headers and body == plain
    # the address without the content's hash (an old page, a hand-typed address) must be checked every time
    status, headers, _ = _get(server, "/static/plotly.min.js", **{"Accept-Encoding": "gzip"})
    assert status == 200 and headers["cache-control"] == "no-cache"
