"""``psvs serve`` as a user starts it (a process on 127.0.0.1): an address it cannot listen on is refused in one
line, exit 2, before uvicorn starts; a running server refuses a request naming another host (DNS rebinding) and
a change from another origin (CSRF), takes the token it printed, and its terminal holds only psvs's words --
no access log, no uvicorn warning, no libpng line."""
import http.client
import json
import re
import select
import signal
import socket
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest

#: Longest a refusal or a start may take on a busy machine (s).
START_S = 120


def psvs_serve(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "psvs", "serve", *map(str, args)], capture_output=True, text=True,
                          timeout=START_S, cwd=cwd)


@pytest.fixture
def busy_port():
    """A port of 127.0.0.1 another socket listens on."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


@pytest.fixture
def image(tmp_path):
    """A 640 x 480 grey PNG (the default rig's camera): a source that costs nothing to open."""
    path = tmp_path / "still.png"
    cv2.imwrite(str(path), np.random.default_rng(0).integers(0, 256, (480, 640), np.uint8))
    return path


def one_line(done: subprocess.CompletedProcess, says: str) -> None:
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert len(lines) == 1 and lines[0].startswith("psvs serve: ") and says in lines[0], done.stderr
    assert done.stdout == "", done.stdout


def test_a_port_in_use_is_one_line(busy_port, image):
    t0 = time.monotonic()
    done = psvs_serve("--image", image, "--port", busy_port)
    one_line(done, f"cannot listen on 127.0.0.1:{busy_port}: the port is in use")
    assert time.monotonic() - t0 < START_S


@pytest.mark.parametrize("args, says", [
    (("--host", "nosuch.invalid"), "--host 'nosuch.invalid' does not resolve"),
    (("--host", "198.51.100.7"), "cannot listen on 198.51.100.7:0: --host is not an address of this machine"),
    (("--host", "http://localhost"), "--host must be a host name or an IP address"),
    (("--port", "65536"), "--port must be 0-65535, got 65536"),
    (("--port", "http"), "argument --port: invalid int value: 'http'"),
    (("--allow-host", "evil.example/x"), "--allow-host must be a host name, an IP address or NAME:PORT"),
])
def test_an_address_it_cannot_listen_on_is_one_line(image, args, says):
    done = psvs_serve("--image", image, "--port", "0", *args)
    one_line(done, says)


class Server:
    """A ``psvs serve`` process on a free port of 127.0.0.1: its port, its token, raw requests to it."""

    def __init__(self, *args):
        self.proc = subprocess.Popen([sys.executable, "-m", "psvs", "serve", "--port", "0", *map(str, args)],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + START_S
        line = ""
        while not line and time.monotonic() < deadline and self.proc.poll() is None:
            if select.select([self.proc.stdout], [], [], 0.5)[0]:
                line = self.proc.stdout.readline()
        m = re.fullmatch(r"psvs serve: open http://127\.0\.0\.1:(\d+)/\?token=([\w-]+) \(Ctrl-C stops\)\n", line)
        assert m, (line, self.stop())
        self.announced, self.port, self.token = line, int(m[1]), m[2]

    def request(self, method, path, body=b"", headers=None):
        """(status, headers, JSON or bytes) of one request; Host is the server's unless ``headers`` names one."""
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=30)
        try:
            conn.request(method, path, body, {"Host": f"127.0.0.1:{self.port}", **(headers or {})})
            r = conn.getresponse()
            data = r.read()
            kind = r.getheader("content-type", "")
            return r.status, dict(r.getheaders()), json.loads(data) if kind == "application/json" else data
        finally:
            conn.close()

    def stop(self):
        """Ctrl-C; (exit status, stdout, stderr)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        out, err = self.proc.communicate(timeout=60)
        return self.proc.returncode, out, err


def test_a_running_server_refuses_other_hosts_and_origins_and_says_nothing_else(image):
    server = Server("--image", image)
    try:
        auth = {"Authorization": f"Bearer {server.token}"}
        # DNS rebinding: the attacker's name in Host, on an API route and a static file
        for path in ("/api/info", "/static/app.js"):
            status, _, body = server.request("GET", path, headers={"Host": f"attacker.example:{server.port}"})
            assert status == 400 and "is not this server's address" in body["detail"]
            assert server.request("GET", path)[0] == 200
        # CSRF: a text/plain upload from another origin, with and without the token
        _, png = cv2.imencode(".png", np.full((480, 640), 7, np.uint8))
        for extra in ({}, auth):
            status, _, body = server.request("POST", "/api/upload", png.tobytes(),
                                             {"Origin": "http://evil.example", "Content-Type": "text/plain", **extra})
            assert status == 403 and body["detail"].startswith("cross-origin request refused")
        status, _, body = server.request("POST", "/api/upload", png.tobytes(), {"Content-Type": "text/plain", **auth})
        assert status == 415
        js = {"Content-Type": "application/json"}
        assert server.request("POST", "/api/preview", b"{}", js)[0] == 403               # a script, no token
        assert server.request("POST", "/api/preview", b"{}", {**js, **auth})[0] == 200   # the token it printed
        page = {"Origin": f"http://127.0.0.1:{server.port}", "Sec-Fetch-Site": "same-origin"}
        assert server.request("POST", "/api/preview", b"{}", {**js, **page})[0] == 200   # the page
        status, headers, _ = server.request("GET", f"/?token={server.token}")
        assert status == 303 and "SameSite=Strict" in headers["set-cookie"]
        # what used to reach the terminal: a damaged upload (libpng), malformed HTTP (uvicorn's warning)
        status, _, body = server.request("POST", "/api/upload", png.tobytes()[:300], {"Content-Type": "image/png",
                                                                                     **auth})
        assert status == 400 and body["detail"].startswith("not a readable PNG image")
        with socket.create_connection(("127.0.0.1", server.port), timeout=30) as s:
            s.sendall(b"GARBAGE\r\n\r\n")
            assert s.recv(100).startswith(b"HTTP/1.1 400 ")
        assert server.request("GET", "/api/info")[0] == 200
    finally:
        code, out, err = server.stop()
    assert err == "" and out == "", (out, err)
    assert code == 0


def test_sigterm_stops_the_server_with_a_request_held_open(image):
    """A client that sent half a request does not hold the server: SIGTERM (a service manager's stop) ends it
    within the grace of a few seconds, with 143 and one line (adversarial trial: still running 40 s later,
    then exit 0)."""
    server = Server("--image", image)
    with socket.create_connection(("127.0.0.1", server.port), timeout=30) as held:
        held.sendall(f"POST /api/match HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\nContent-Type: application/json"
                     f"\r\nAuthorization: Bearer {server.token}\r\nContent-Length: 100\r\n\r\n{{".encode())
        time.sleep(1.0)
        t0 = time.monotonic()
        server.proc.send_signal(signal.SIGTERM)
        out, err = server.proc.communicate(timeout=60)
    assert time.monotonic() - t0 < 20
    assert server.proc.returncode == 143 and err == "psvs serve: terminated (SIGTERM)\n" and out == "", (out, err)


@pytest.fixture
def uvicorn_loggers():
    """uvicorn's loggers restored after the test (psvs serve sets them for the process it runs in)."""
    import logging
    logs = [logging.getLogger(n) for n in ("uvicorn", "uvicorn.error", "uvicorn.access", "uvicorn.asgi")]
    saved = [(log.handlers, log.propagate) for log in logs]
    yield
    for log, (handlers, propagate) in zip(logs, saved, strict=True):
        log.handlers, log.propagate = handlers, propagate


def test_an_exception_in_a_route_is_one_line_on_the_terminal(capsys, uvicorn_loggers):
    """What uvicorn logs of an exception no handler answered ("Exception in ASGI application" and its
    traceback) reaches the terminal as one line naming it; uvicorn's warnings do not reach it."""
    import logging

    from psvs.cli.serve_cmd import uvicorn_in_one_line
    uvicorn_in_one_line()
    try:
        raise RuntimeError("no frame\n  in the second line: where")
    except RuntimeError:
        logging.getLogger("uvicorn.error").exception("Exception in ASGI application")
    logging.getLogger("uvicorn.error").warning("Invalid HTTP request received.")
    logging.getLogger("uvicorn.access").warning('127.0.0.1:5 - "GET / HTTP/1.1" 200')
    out, err = capsys.readouterr()
    assert out == ""
    assert err == "psvs serve: internal error: RuntimeError: no frame (PSVS_DEBUG=1 shows the traceback)\n"
