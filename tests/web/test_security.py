"""A real uvicorn server (127.0.0.1, background thread) takes 1,000 malformed or oversized requests, answers
each with 4xx, and still answers a normal request correctly afterwards. The requests carry the app's token and
name the server in their Host, so that they reach the routes (the rules on who may send them:
tests/web/test_guard.py)."""
import json
import random
import socket
from urllib.parse import urlparse

import pytest

from psvs.web.app import MAX_BODY_BYTES, create_app
from tests.support.web import DISC, rim_point_px, serving


@pytest.fixture
def server(disc_source):
    """(base URL, token) of the app on the simulated disc, served for real."""
    source, rig = disc_source
    app = create_app(source, rig)
    with serving(app) as url:
        yield url, app.state.access.token


def _raw(base, data: bytes) -> bytes:
    """Send raw bytes, return the raw reply. The server may answer and close before taking a whole oversized
    body: what it sent is still read."""
    url = urlparse(base)
    with socket.create_connection((url.hostname, url.port), timeout=30) as s:
        try:
            s.sendall(data)
        except (BrokenPipeError, ConnectionResetError):
            pass
        out = b""
        try:
            while chunk := s.recv(65536):
                out += chunk
        except ConnectionResetError:
            pass
        return out


def _request(base, method, path, body=b"", headers=None):
    """(status, body) of one HTTP/1.1 request on a fresh connection (Host: the server's address)."""
    url = urlparse(base)
    head = {"Host": url.netloc, "Connection": "close", "Content-Length": str(len(body)), **(headers or {})}
    data = f"{method} {path} HTTP/1.1\r\n".encode() + b"".join(f"{k}: {v}\r\n".encode() for k, v in head.items())
    reply = _raw(base, data + b"\r\n" + body)
    status_line, _, rest = reply.partition(b"\r\n")
    assert status_line.startswith(b"HTTP/1.1 "), reply[:80]
    return int(status_line.split()[1]), rest.partition(b"\r\n\r\n")[2]


def _bad_requests(rng, token):
    """(method, path, body, headers) of malformed, hostile or oversized requests, with the token."""
    auth = {"Authorization": f"Bearer {token}"}
    js = {"Content-Type": "application/json", **auth}
    png = {"Content-Type": "image/png", **auth}
    bodies = [b"{", b"[]", b"null", b'{"seed": "x"}', b'{"seed": [1e309, 2]}', b'{"seed": [1, 2, 3]}',
              b'{"steps": [{"op": "median", "ksize": 99999}, {"op": "roberts"}]}', b'{"steps": "median"}',
              b'{"steps": [{"op": "../../etc/passwd"}]}', b'{"near_mm": "a"}', b'{"model": {}}', b"\xff\xfe\x00",
              json.dumps({"steps": [{"op": "median"}] * 50}).encode(), b'{"seed": [-50, -50]}']
    paths = ["/static/../app.py", "/static/%2e%2e/%2e%2e/etc/passwd", "/static/..%2fapp.py", "/../../etc/passwd",
             "/api/export/..%2f..%2fetc%2fpasswd", "/api/nope", "/static/", "/api/image.png/../../x"]
    for i in range(1000):
        kind = i % 5
        if kind == 0:
            yield "POST", rng.choice(["/api/match", "/api/preview", "/api/live/start"]), rng.choice(bodies), js
        elif kind == 1:
            yield "GET", rng.choice(paths), b"", {}
        elif kind == 2:   # declared oversized: rejected before the body is read
            yield "POST", "/api/upload", b"", {"Content-Length": str(MAX_BODY_BYTES * 10), **png}
        elif kind == 3:
            yield "POST", "/api/upload", bytes(rng.getrandbits(8) for _ in range(64)), png
        else:
            yield rng.choice(["PUT", "DELETE", "PATCH"]), "/api/match", b"{}", js


def test_thousand_bad_requests_leave_the_server_working(server, disc_source):
    live_server, token = server
    rng = random.Random(8)
    statuses = []
    for method, path, body, headers in _bad_requests(rng, token):
        status, _ = _request(live_server, method, path, body, headers)
        statuses.append(status)
    assert len(statuses) == 1000 and all(400 <= s < 500 for s in statuses), sorted(set(statuses))
    assert {400, 404, 405, 413, 422} <= set(statuses) and 403 not in statuses     # they reach the routes
    # really oversized bodies (streamed) and garbage that is not HTTP at all
    big = b"\x89PNG\r\n\x1a\n" + b"\0" * (MAX_BODY_BYTES + 1)
    for _ in range(3):
        assert _request(live_server, "POST", "/api/upload", big,
                        {"Content-Type": "image/png", "Authorization": f"Bearer {token}"})[0] == 413
    for junk in (b"GARBAGE\r\n\r\n", b"\x16\x03\x01\x02\x00" * 50):
        reply = _raw(live_server, junk)
        assert reply == b"" or reply.startswith(b"HTTP/1.1 400 "), reply[:80]
    # the server still answers, correctly
    status, body = _request(live_server, "GET", "/api/info")
    assert status == 200 and json.loads(body)["image_size_px"] == [640, 480]
    _, rig = disc_source
    u, v = rim_point_px(rig, "left")
    status, body = _request(live_server, "POST", "/api/match", json.dumps({"seed": [u, v]}).encode(),
                            {"Content-Type": "application/json", "Authorization": f"Bearer {token}"})
    assert status == 200
    assert json.loads(body)["pairs"][0]["median_z_mm"] == pytest.approx(DISC["z_mm"], rel=0.005)
