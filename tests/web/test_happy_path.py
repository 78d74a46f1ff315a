"""The builder's happy path through the page, by clicks, end to end (issue 44 item 5): a simulated build (the
misaligned build's hand-held card video, served with the clear design) is seen in 3-D, its card views are
captured from the video, calibrated in the server, the screw turns read against the design, and a textured
scene's dense depth drawn as a cloud through the calibrated build. Truth: the scene's own depth map; the
request log (nothing but the server); the console (no error)."""
from urllib.parse import urlsplit

import cv2
import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.simulate.builtin import textured
from psvs.simulate.render import render
from psvs.web.app import create_app
from psvs.web.sources import video_source
from tests.support.browser import shot
from tests.support.web import serving

pytestmark = pytest.mark.slow        # a capture from video, a calibration, a dense run


def test_design_capture_calibrate_align_dense_cloud(webgl_page, hand_video, tmp_path):
    page = webgl_page
    errors, hosts = [], set()
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("request", lambda r: hosts.add(urlsplit(r.url).netloc) if r.url.startswith("http") else None)
    scene = render(textured(800.0), load_rig("misaligned"), supersample=1, seed=7, truth=True)
    still = tmp_path / "scene.png"
    cv2.imwrite(str(still), scene.image)
    views = tmp_path / "views"
    with serving(create_app(video_source(str(hand_video.path)), load_rig("clear"), "clear")) as url:
        # 1. Design: the rig in use, in 3-D
        page.goto(url + "/")
        page.wait_for_selector("body[data-ready='1']", timeout=60000)
        page.wait_for_selector("#rig3d canvas", timeout=30000)
        # 3. Capture: the card's file and a new folder chosen in the page, then views from the video
        page.click("#workflow a[data-step='capture']")
        page.set_input_files("#capture-target", str(hand_video.target))
        page.fill("#capture-dir", str(views))
        page.click("#capture-setup")
        page.wait_for_function("document.getElementById('capture-hint').textContent.includes('views go to')",
                               timeout=30000)
        page.fill("#capture-views", "9")
        page.click("#capture-start")
        page.wait_for_function("document.getElementById('capture-events').textContent.includes('enough to "
                               "calibrate')", timeout=300000)
        # ... calibrated in the server; the build is the rig in use from then on
        page.click("#calibrate-run")
        page.wait_for_function("['1', 'error'].includes(document.body.dataset.calibrateDone)", timeout=400000)
        assert page.evaluate("document.body.dataset.calibrateDone") == "1", page.inner_text("#calibrate-status")
        assert str(views / "build.toml") in page.inner_text("#rig") and "calibrated" in page.inner_text("#rig")
        shot(page, "web_happy_capture.png")
        # 4. Align: the calibrated build against its design: a turn for each of the eight screws
        page.click("#workflow a[data-step='align']")
        page.set_input_files("#adjust-rig", str(views / "build.toml"))
        page.select_option("#adjust-design", "clear")
        page.click("#adjust-run")
        page.wait_for_selector("body[data-adjust-done='1']", timeout=120000)
        assert page.locator("#adjust-turns tbody td.turn").count() == 8
        # 7. Dense: a textured scene through the build, opened in the page; its cloud in 3-D at the scene's depth
        page.set_input_files("#upload", str(still))
        page.wait_for_function("document.getElementById('source').textContent === 'image: scene.png'", timeout=30000)
        page.click("#workflow a[data-step='dense']")
        page.click("#dense")
        page.wait_for_function("Number(document.getElementById('dense-cloud').dataset.points) > 5000",
                               timeout=300000)
        page.wait_for_timeout(500)
        cloud = cv2.imdecode(np.frombuffer(page.locator("#dense-cloud").screenshot(), np.uint8), cv2.IMREAD_GRAYSCALE)
        assert cloud.std() > 5                                  # drawn, not a blank canvas
        z = float(page.eval_on_selector("#dense-depth", "e => e.dataset.mm"))
        truth = scene.truth.depth_left_mm
        assert abs(z / float(np.nanmedian(truth)) - 1) <= 0.1, (z, float(np.nanmedian(truth)))
        shot(page, "web_happy_dense.png")
    assert hosts == {urlsplit(url).netloc}, hosts             # every request went to the server
    assert errors == [], errors
