"""Live mode's dense cloud in 3-D (issue 44: the depth stream as a live point cloud): ``GET /api/live/cloud`` is
the latest dense frame's points by value, at the scene's depth, and the Live step draws it, labelled as live
mode's points: those its latest echo test supported. Truth: the textured scene's own depth map."""
import time

import cv2
import numpy as np
import pytest

from psvs.io.video import write_video
from psvs.optics.rig import default_rig
from psvs.simulate.builtin import textured
from psvs.simulate.render import render
from psvs.web.app import create_app
from psvs.web.sources import video_source
from tests.support.web import local_client, serving


@pytest.fixture(scope="module")
def scene_video(tmp_path_factory):
    """Three frames of the textured scene (the same still: its truth holds for every frame)."""
    r = render(textured(800.0), default_rig(), supersample=1, seed=3, truth=True)
    path = tmp_path_factory.mktemp("live_cloud") / "textured.avi"
    write_video(path, [r.image] * 3, 30.0)
    return path, r.truth.depth_left_mm


def test_the_cloud_is_the_latest_dense_frames_points(scene_video):
    path, truth = scene_video
    with local_client(create_app(video_source(str(path)), default_rig())) as c:
        assert c.get("/api/live/cloud").status_code == 404
        assert c.post("/api/live/start", json={"dense": True, "check": False}).json() == {"running": True}
        t0 = time.monotonic()
        while not c.get("/api/live/state").json().get("dense"):
            assert time.monotonic() - t0 < 120
            time.sleep(0.1)
        c.post("/api/live/stop")                 # the latest frame stays: the cloud is read once it is still
        got = c.get("/api/live/cloud").json()
        d = c.app.state.session.live.dense()
    assert got["frame"] == d.frame
    assert got["tested"] is True and got["of_points"] == len(d.points_mm) > 1000
    k = np.unique(np.linspace(0, len(d.points_mm) - 1, min(20000, len(d.points_mm))).astype(int))
    np.testing.assert_allclose(got["points_mm"], d.points_mm[k], atol=0.005 + 1e-9)
    # at the scene's depth: each point's Z against the truth at its pixel (the map's grid is the image's here)
    u, v = d.pixels[k].T.astype(int)
    z = np.array(got["points_mm"])[:, 2]
    ok = np.isfinite(truth[v, u])
    err = np.abs(z[ok] / truth[v, u][ok] - 1)
    # live mode's fast map, its points those the echo test supported: 96.5 % within 2 % here (74 % when they
    # were every answered pixel); a still's trusted points hold 90 % (tests/web/test_rig3d.py)
    assert ok.mean() > 0.9 and np.median(err) <= 0.01 and np.mean(err <= 0.02) >= 0.9


def test_the_live_step_draws_the_cloud(webgl_page, scene_video):
    page = webgl_page
    with serving(create_app(video_source(str(scene_video[0])), default_rig())) as url:
        page.goto(url + "/#live")
        page.wait_for_selector("body[data-ready='1']", timeout=60000)
        page.check("#live-dense")
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-cloud').dataset.points) > 1000", timeout=120000)
        page.click("#live-stop")
        page.wait_for_timeout(500)
        img = cv2.imdecode(np.frombuffer(page.locator("#live-cloud").screenshot(), np.uint8), cv2.IMREAD_GRAYSCALE)
        assert img.std() > 5
        # the note and the cloud's frame read together (a drawing may land between two separate reads)
        note, frame = page.evaluate("[document.getElementById('live-cloud-note').innerText, "
                                    "document.getElementById('live-cloud').dataset.frame]")
        assert "the echo test supported beyond chance" in note and f"of frame {frame}" in note, note
