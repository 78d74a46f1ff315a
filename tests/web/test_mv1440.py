"""`psvs serve`'s API on the machine-vision camera (1440 x 1080 px, 3.45 um, lens fall-off and distortion):
a double-click on a disc's rim in the left view and the automatic mode both give the disc's depth, and the
page sizes its canvas from the image (no 640 x 480 left in it)."""
from pathlib import Path

import cv2
import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.live.simulated import disc_scene
from psvs.optics.project import project_points
from psvs.simulate.render import render
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.web import local_client

DISC = {"z_mm": 700.0, "radius_mm": 40.0, "x_mm": 30.0, "y_mm": -20.0}
STATIC = Path(__file__).resolve().parents[2] / "src" / "psvs" / "web" / "static"


@pytest.fixture(scope="module", params=["mv1440", "mv1440_misaligned"])
def served(request):
    rig = load_rig(request.param)
    grey = render(disc_scene(**DISC), rig, supersample=1, seed=3).image
    with local_client(create_app(image_source("disc", grey), rig)) as client:
        yield client, rig


def _rim(rig, view, angle_rad=np.pi):
    p = [DISC["x_mm"] + DISC["radius_mm"] * np.cos(angle_rad), DISC["y_mm"] + DISC["radius_mm"] * np.sin(angle_rad),
         DISC["z_mm"]]
    uv, ok = project_points([p], rig, view)
    assert ok[0]
    return uv[0]


@pytest.mark.slow
def test_info_double_click_and_automatic(served):
    client, rig = served
    info = client.get("/api/info").json()
    assert info["image_size_px"] == [1440, 1080]
    img = cv2.imdecode(np.frombuffer(client.get("/api/image.png").content, np.uint8), cv2.IMREAD_UNCHANGED)
    assert img.shape == (1080, 1440)
    u, v = _rim(rig, "left")
    res = client.post("/api/match", json={"seed": [u - 3, v]}).json()
    (pair,) = res["pairs"]
    assert pair["median_z_mm"] == pytest.approx(DISC["z_mm"], rel=0.005)
    ur, vr = _rim(rig, "right")
    assert np.min(np.hypot(*(np.array(pair["right_px"]) - [ur, vr]).T)) < 2.0
    assert pair["median_disparity_px"] > 255          # beyond a uint8 disparity
    auto = client.post("/api/match", json={"seed": None}).json()
    assert len(auto["pairs"]) == 1 and auto["pairs"][0]["median_z_mm"] == pytest.approx(DISC["z_mm"], rel=0.005)


def test_the_page_takes_its_size_from_the_image():
    """The canvas is sized by app.js from the image it loads; the HTML holds no camera's size."""
    html = (STATIC / "index.html").read_text()
    assert "640" not in html and "480" not in html
    assert "canvas.width = state.image.width; canvas.height = state.image.height;" in (STATIC / "app.js").read_text()
