"""The double-click's snap radius is an angle: SNAP_PX px of the paper's camera, scaled to the rig's camera
(psvs.optics.scale.pixel_scale), so a click so many tenths of a degree off an edge snaps alike on the
640 x 480 rig and on mv1440 (1440 x 1080, 3.45 um, 8 mm: 2.05 of its px per paper px)."""
import numpy as np
import pytest

from psvs import default_rig
from psvs.imaging.pipeline import PAPER
from psvs.io.params import load_rig
from psvs.optics.scale import pixel_scale
from psvs.web.api_match import SNAP_PX, snap_px, snap_seed
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.web import local_client

RIGS = {"default": default_rig, "mv1440": lambda: load_rig("mv1440")}


def _step(rig, u_edge: int) -> np.ndarray:
    """The rig's image size, dark left of column ``u_edge`` and bright from it on: one vertical edge."""
    w, h = rig.camera.image_size_px
    grey = np.full((h, w), 40, np.uint8)
    grey[:, u_edge:] = 210
    return grey


@pytest.mark.parametrize("name", RIGS)
def test_a_click_snaps_within_the_same_angle(name):
    rig = RIGS[name]()
    s = pixel_scale(rig.camera)
    assert snap_px(rig) == pytest.approx(SNAP_PX * s)
    u_edge, v = rig.camera.image_size_px[0] // 3, rig.camera.image_size_px[1] / 2
    grey = _step(rig, u_edge)
    for paper_px in (4.0, -4.0):               # 4 paper px off (0.2°): 4 px here, 8.2 px on mv1440
        u, _ = snap_seed(grey, PAPER, (u_edge + paper_px * s, v), snap_px(rig))
        assert abs(u - u_edge) <= 1
    with pytest.raises(ValueError, match=r"^no edge within [\d.]+ px of"):   # 8 paper px off: beyond 0.3°
        snap_seed(grey, PAPER, (u_edge + 8.0 * s, v), snap_px(rig))


def test_the_api_snaps_with_the_rig_radius():
    """On mv1440 a click 10 px off the edge (under 5 px of the paper's camera) snaps; the page is told the
    radius in the image's own px."""
    rig = load_rig("mv1440")
    u_edge = 500
    with local_client(create_app(image_source("step", _step(rig, u_edge)), rig)) as client:
        assert client.get("/api/info").json()["snap_px"] == pytest.approx(12.31, abs=0.01)
        res = client.post("/api/match", json={"seed": [u_edge + 10.0, 300.0]})
        assert res.status_code == 200, res.text
        assert abs(res.json()["seed_px"][0] - u_edge) <= 1
        far = client.post("/api/match", json={"seed": [u_edge + 20.0, 300.0]})
        assert far.status_code == 400 and "no edge within 12.3 px" in far.json()["detail"]
