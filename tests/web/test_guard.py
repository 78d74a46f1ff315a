"""Who may drive the app (psvs.web.guard), rule by rule, with FastAPI's TestClient: a Host naming another server
is refused on every route (DNS rebinding), a change from another origin is refused (CSRF), a body of a type a
browser sends across origins without asking is refused (415), a client that is not the page needs the token,
and the page itself needs nothing."""
import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from psvs.web.app import ROUTERS, create_app
from psvs.web.guard import LOOPBACK, Access, split_host
from psvs.web.sources import image_source

PORT = 8000
BASE = f"http://127.0.0.1:{PORT}"
PAGE = {"Origin": BASE, "Sec-Fetch-Site": "same-origin"}      # what Chromium sends with the page's fetch()


@pytest.fixture(scope="module")
def still():
    return np.random.default_rng(3).integers(0, 256, (480, 640), np.uint8)


@pytest.fixture
def app(disc_source):
    source, rig = disc_source
    return create_app(source, rig)


@pytest.fixture
def client(app):
    """A browser or script on this machine reaching the server at 127.0.0.1:8000 (no token, no Origin)."""
    with TestClient(app, base_url=BASE) as c:
        yield c


def png_bytes(img) -> bytes:
    return cv2.imencode(".png", img)[1].tobytes()


def served(client) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(client.get("/api/image.png").content, np.uint8), cv2.IMREAD_UNCHANGED)


def bearer(app) -> dict:
    return {"Authorization": f"Bearer {app.state.access.token}"}


# ---- Host: every route, static files included ------------------------------------------------------------------

@pytest.mark.parametrize("path", ["/api/info", "/api/image.png", "/static/app.js", "/", "/api/nope"])
@pytest.mark.parametrize("host", ["attacker.example", f"attacker.example:{PORT}", f"127.0.0.1:{PORT + 1}",
                                  f"localhost.attacker.example:{PORT}", "127.0.0.1:80", "", "a b", "[::1"])
def test_a_host_naming_another_server_is_refused_on_every_route(client, path, host):
    r = client.get(path, headers={"Host": host})
    assert r.status_code == 400, r.text
    assert r.headers["content-type"] == "application/json"
    detail = r.json()["detail"]
    assert ("is not this server's address" in detail or detail == "no Host header") and "\n" not in detail


@pytest.mark.parametrize("host", [f"127.0.0.1:{PORT}", f"localhost:{PORT}", f"[::1]:{PORT}", f"LOCALHOST.:{PORT}"])
def test_the_loopback_names_on_the_servers_port_are_served(client, host):
    assert client.get("/api/info", headers={"Host": host}).status_code == 200
    assert client.get("/static/app.js", headers={"Host": host}).status_code == 200


def test_a_refused_host_changes_nothing(app, client, still):
    """A rebinding page's upload (its own name in Host) is refused even with the right Origin of its name."""
    before = served(client)
    r = client.post("/api/upload", content=png_bytes(still),
                    headers={"Host": "attacker.example:8000", "Origin": "http://attacker.example:8000",
                             "Content-Type": "image/png", **bearer(app)})
    assert r.status_code == 400
    assert np.array_equal(served(client), before)


# ---- Origin: no change from another origin ----------------------------------------------------------------------

@pytest.mark.parametrize("headers", [
    {"Origin": "http://evil.example"},
    {"Origin": f"http://127.0.0.1:{PORT + 1}"},                    # another server on this machine
    {"Origin": f"https://127.0.0.1:{PORT}"},
    {"Origin": "null"},                                             # a sandboxed frame, a file:// page
    {"Sec-Fetch-Site": "cross-site"},
    {"Sec-Fetch-Site": "same-site"},                                # another port of 127.0.0.1
    {"Origin": BASE, "Sec-Fetch-Site": "cross-site"},
    {"Origin": "http://evil.example", "Sec-Fetch-Site": "same-origin"},
])
def test_a_cross_origin_change_is_refused_even_with_the_token(app, client, still, headers):
    before = served(client)
    for token in ({}, bearer(app)):
        r = client.post("/api/upload", content=png_bytes(still), headers={"Content-Type": "image/png",
                                                                          **headers, **token})
        assert r.status_code == 403 and r.json()["detail"].startswith("cross-origin request refused"), r.text
        r = client.post("/api/match", json={"seed": None}, headers={**headers, **token})
        assert r.status_code == 403
    assert np.array_equal(served(client), before)


def test_every_route_that_changes_something_is_guarded(app, client):
    """Each POST route of the app, sent as a script without the token (and as another origin's page): 403. The
    GET routes only read (exports, states, frames), and need neither."""
    routes = [r for module in ROUTERS for r in module.router.routes]
    posts = sorted(r.path for r in routes if "POST" in r.methods)
    assert len(posts) == 20 and {"/api/source/video", "/api/source/camera", "/api/cameras"} <= set(posts), posts
    for path in posts:
        assert client.post(path, json={}).status_code == 403, path
        assert client.post(path, json={}, headers={"Origin": "http://evil.example"}).status_code == 403, path
        assert client.put(path, json={}).status_code == 403, path
        assert client.delete(path).status_code == 403, path
    gets = [r.path.replace("{fmt}", "csv").replace("{name}", "mount.stl") for r in routes if "GET" in r.methods]
    assert len(gets) == 16 and all(client.get(p).status_code in (200, 404, 409, 422) for p in gets), gets


# ---- Body type: what a browser sends across origins without a preflight never reaches a route --------------------

@pytest.mark.parametrize("path", ["/api/match", "/api/preview", "/api/live/start", "/api/upload", "/api/source/video",
                                  "/api/source/camera", "/api/cameras"])
@pytest.mark.parametrize("ctype", ["text/plain", "text/plain;charset=UTF-8", "application/x-www-form-urlencoded",
                                   "multipart/form-data; boundary=x", None])
def test_a_body_of_another_type_is_415(app, client, still, path, ctype):
    """Refused whoever sends it (the token, the page): a JSON route takes application/json, the upload an image
    type (image/png ...)."""
    body = png_bytes(still) if path == "/api/upload" else b'{"seed": null}'
    before = served(client)
    for who in (bearer(app), PAGE):
        headers = {**who, **({} if ctype is None else {"Content-Type": ctype})}
        r = client.post(path, content=body, headers=headers)
        assert r.status_code == 415, r.text
        wanted = {"/api/upload": "an image (image/png, image/jpeg, ",
                  "/api/source/video": "a video (video/x-msvideo, video/avi, "}.get(path, "application/json, got ")
        assert r.json()["detail"].startswith(f"POST {path} takes {wanted}")
    assert np.array_equal(served(client), before)
    wrong = "application/json" if path in ("/api/upload", "/api/source/video") else "image/png"
    assert client.post(path, content=body, headers={**PAGE, "Content-Type": wrong}).status_code == 415


def test_a_post_without_a_body_needs_no_type(app, client):
    assert client.post("/api/live/stop", headers=bearer(app)).json() == {"running": False}


# ---- The token: scripts and other clients -------------------------------------------------------------------

def test_a_script_needs_the_token(app, client, still):
    r = client.post("/api/preview", json={})
    assert r.status_code == 403 and "needs the token" in r.json()["detail"]
    for wrong in ("Bearer nope", f"Bearer {app.state.access.token}x", "Basic dXNlcjpwYXNz", "Bearer"):
        r = client.post("/api/preview", json={}, headers={"Authorization": wrong})
        assert r.status_code == 403 and r.json()["detail"].startswith("wrong token"), wrong
    assert client.post("/api/preview", json={}, headers=bearer(app)).status_code == 200
    r = client.post("/api/upload", content=png_bytes(still), headers={"Content-Type": "image/png", **bearer(app)})
    assert r.status_code == 200 and np.array_equal(served(client), still)


def test_each_app_has_its_own_token(disc_source):
    source, rig = disc_source
    a, b = create_app(source, rig), create_app(source, rig)
    assert a.state.access.token != b.state.access.token and len(a.state.access.token) >= 40
    with TestClient(b, base_url=BASE) as c:
        assert c.post("/api/preview", json={}, headers=bearer(a)).status_code == 403


def test_the_page_opened_with_the_token_gets_a_cookie(app, client):
    """/?token=T: a cookie (HttpOnly, SameSite=Strict, named for the port) and a redirect to /, so the address
    bar does not keep the token; the cookie then stands for the token. A wrong token in the address: 403."""
    token = app.state.access.token
    r = client.get(f"/?token={token}", follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"] == "/"
    cookie = r.headers["set-cookie"]
    assert cookie.startswith(f"psvs-token-{PORT}={token};") and "HttpOnly" in cookie and "SameSite=Strict" in cookie
    assert client.get("/").status_code == 200
    assert client.post("/api/preview", json={}).status_code == 200            # the cookie, no header
    client.cookies.clear()
    assert client.post("/api/preview", json={}).status_code == 403
    r = client.get("/?token=nope", follow_redirects=False)
    assert r.status_code == 403 and "set-cookie" not in r.headers
    client.cookies.set(f"psvs-token-{PORT}", "stale")                          # an earlier run's cookie
    assert client.post("/api/preview", json={}).status_code == 403


# ---- The page itself ------------------------------------------------------------------------------------------

def test_the_page_works_without_the_user_doing_anything(client, still, disc_source):
    """What the page does, as Chromium sends it: load /, its files and the image, preview, match, upload,
    export -- no token anywhere, only its own Origin. A cookie of an earlier run does not get in the way."""
    client.cookies.set(f"psvs-token-{PORT}", "of-an-earlier-run")
    assert 'id="image"' in client.get("/").text and client.get("/static/app.js").status_code == 200
    assert client.get("/api/info").status_code == 200 and client.get("/api/image.png").status_code == 200
    assert client.post("/api/preview", json={}, headers=PAGE).status_code == 200
    assert client.post("/api/match", json={"seed": None}, headers=PAGE).status_code == 200
    assert client.get("/api/export/json").status_code == 200
    assert client.post("/api/match", json={"seed": None}, headers={"Origin": BASE}).status_code == 200  # Firefox
    r = client.post("/api/upload", content=png_bytes(still), headers={"Content-Type": "image/png", **PAGE})
    assert r.status_code == 200 and np.array_equal(served(client), still)
    # the page opened as http://localhost:8000/ is the same server
    local = {"Host": f"localhost:{PORT}", "Origin": f"http://localhost:{PORT}"}
    assert client.post("/api/preview", json={}, headers=local).status_code == 200


# ---- Access: the names a bind answers to --------------------------------------------------------------------

def test_the_names_of_a_bind():
    loop = Access.for_bind("127.0.0.1", "127.0.0.1", token="t")
    assert loop.names == LOOPBACK and not loop.any_local_address
    assert Access.for_bind("localhost", "127.0.0.1", token="t").names == LOOPBACK
    assert Access.for_bind("::1", "::1", token="t").names == LOOPBACK
    lan = Access.for_bind("rig-pc.lan", "192.0.2.7", ("rig-pc", "localhost:9000"), token="t")
    assert lan.names == {"rig-pc.lan", "192.0.2.7", "rig-pc"} and lan.pairs == {("localhost", 9000)}
    assert lan.host_allowed("rig-pc:8000", 8000) and lan.host_allowed("localhost:9000", 8000)   # a tunnel
    assert not lan.host_allowed("localhost:8000", 8000) and not lan.host_allowed("127.0.0.1:8000", 8000)
    assert not lan.host_allowed("rig-pc:8001", 8000)


def test_a_wildcard_bind_answers_to_this_machines_names_and_addresses():
    import socket
    every = Access.for_bind("0.0.0.0", "0.0.0.0", ("rig.example.org",), token="t")
    me = socket.gethostname().lower()
    assert LOOPBACK | {me, "rig.example.org"} <= every.names and every.any_local_address
    assert every.host_allowed(f"{me}:8000", 8000) and every.host_allowed("127.0.0.2:8000", 8000)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:        # this machine's address toward a LAN
        try:
            s.connect(("192.0.2.1", 9))
            mine = s.getsockname()[0]
        except OSError:
            mine = "127.0.0.1"
    assert every.host_allowed(f"{mine}:8000", 8000)
    # an address for documentation (TEST-NET-2, RFC 5737), no machine's; a name of another
    assert not every.host_allowed("198.51.100.7:8000", 8000) and not every.host_allowed("attacker.example:8000", 8000)


@pytest.mark.parametrize("allow", ["a b", "http://x", "x:0", "x:99999", "[::1", "x/y"])
def test_a_malformed_allow_host_is_refused(allow):
    with pytest.raises(ValueError, match="--allow-host must be a host name, an IP address or NAME:PORT"):
        Access.for_bind("127.0.0.1", allow=(allow,))


@pytest.mark.parametrize("value, parsed", [
    ("127.0.0.1:8000", ("127.0.0.1", 8000)), ("[::1]:8000", ("::1", 8000)), ("[0:0::1]", ("::1", None)),
    ("LocalHost.", ("localhost", None)), ("rig_pc:1", ("rig_pc", 1)), ("::1", ("::1", None)),
    ("x:", None), ("x:65536", None), ("a b", None), ("[rig]:80", None), ("", None), ("é.example", None),
])
def test_split_host(value, parsed):
    assert split_host(value) == parsed


def test_an_image_source_app_is_guarded_too(still):
    """The rules belong to every app create_app builds, whatever its source."""
    from psvs import default_rig
    app = create_app(image_source("still.png", still), default_rig())
    with TestClient(app, base_url=BASE) as c:
        assert c.get("/api/info", headers={"Host": "attacker.example"}).status_code == 400
        assert c.post("/api/preview", json={}).status_code == 403
