"""The web tests' server and scene: the disc they show, a free port, a client from a loopback address, the app
served by uvicorn in a thread, a point on the disc's rim."""
import contextlib
import socket
import threading
import time

import numpy as np
import uvicorn
from fastapi.testclient import TestClient

#: The browser test's object: a fronto-parallel disc; every point of its rim is at this depth (mm).
DISC = {"z_mm": 650.0, "radius_mm": 30.0, "x_mm": -10.0, "y_mm": 15.0}


#: The headers of an upload as the page sends it (the PNG's bytes as the body).
PNG = {"Content-Type": "image/png"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def local_client(app) -> TestClient:
    """A TestClient as a script on this machine drives the app: ``Host: 127.0.0.1`` (a name the app answers to)
    and the app's token (``Authorization: Bearer``; psvs.web.guard)."""
    return TestClient(app, base_url="http://127.0.0.1",
                      headers={"Authorization": f"Bearer {app.state.access.token}"})


@contextlib.contextmanager
def serving(app):
    """Run ``app`` on a real uvicorn server (127.0.0.1, free port, background thread); yields its base URL."""
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="error"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    t0 = time.monotonic()
    while not server.started:
        assert thread.is_alive() and time.monotonic() - t0 < 30, "server did not start"
        time.sleep(0.05)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=10)


def rim_point_px(rig, view="left", angle_rad=np.pi):
    """Where a point of the disc's rim (at angle_rad around it) appears in a view, (u, v) px."""
    from psvs.optics.project import project_points
    p = [DISC["x_mm"] + DISC["radius_mm"] * np.cos(angle_rad), DISC["y_mm"] + DISC["radius_mm"] * np.sin(angle_rad),
         DISC["z_mm"]]
    uv, ok = project_points([p], rig, view)
    assert ok[0]
    return uv[0]
