"""The web UI's live page from a Basler camera: pylon's emulator (PYLON_CAMEMU) serving psvs's simulated
complex images through the real pypylon path, in headless Chromium."""
import os

import numpy as np

os.environ.setdefault("PYLON_CAMEMU", "1")       # before pypylon is first imported

from psvs.io.params import load_rig  # noqa: E402
from psvs.live.camera import Acquisition, parse_camera  # noqa: E402
from psvs.web.app import create_app  # noqa: E402
from psvs.web.sources import camera_source  # noqa: E402
from tests.support.browser import dblclick_px, shot
from tests.support.video import FRAMES, write_frames  # noqa: E402
from tests.support.web import serving  # noqa: E402


def test_live_page_from_the_emulated_basler_camera(page, tmp_path):
    """serve --camera basler:0 (software trigger): the still is the camera's first frame; double-click the disc's
    rim, start live: the page shows the camera's frames and each one's depth within 1 % of its truth (the
    emulator serves the folder's five frames in a loop: frame k is file k mod 5)."""
    _, served, seed = write_frames(tmp_path, "default", 8)
    truth = 700.0 + np.array([0.0, 25.0, 50.0, 25.0, 0.0])
    features = (("TestImageSelector", "Off"), ("ImageFileMode", "On"), ("ImageFilename", str(served)))
    source = camera_source(parse_camera("basler:0"), Acquisition(trigger="software", features=features))
    assert source.kind == "camera" and source.still.shape == (480, 640)
    with serving(create_app(source, load_rig("default"))) as url:
        page.goto(url + "/#measure")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        dblclick_px(page, *map(float, seed.split(",")))
        page.wait_for_function("document.getElementById('depth').dataset.mm", timeout=30000)
        z0 = float(page.get_attribute("#depth", "data-mm"))
        assert abs(z0 - truth[0]) <= 0.01 * truth[0]
        page.click("#workflow a[data-step='live']")
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-frame').textContent) >= 12", timeout=60000)
        page.click("#live-stop")
        frame, z = page.evaluate("() => [Number(document.getElementById('live-frame').textContent), "
                                 "Number(document.getElementById('live-depth').dataset.mm)]")
        assert abs(z - truth[frame % FRAMES]) <= 0.01 * truth[frame % FRAMES], (frame, z)
        assert float(page.inner_text("#live-fps")) > 0
        shot(page, "web_live_basler.png")


def test_a_camera_chosen_in_the_live_step(page, tmp_path):
    """psvs serve on a still image; in the Live step: Find cameras lists the emulated Basler, the user types its
    features (one a line) and a software trigger, Use this camera serves it (the step's status names it), and
    live mode (dense depth) then reads its frames."""
    _, served, _ = write_frames(tmp_path, "default", 8)
    from psvs.web.sources import image_source
    with serving(create_app(image_source("still.png", np.full((480, 640), 90, np.uint8)), load_rig("default"))) \
            as url:
        page.goto(url + "/#live")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        box = "#step-live .camera-choice"
        page.click(f"{box} .camera-find")
        page.wait_for_function(f"[...document.querySelectorAll('{box} .camera-list option')]"
                               ".some(o => o.value === 'basler:0815-0000')", timeout=30000)
        assert page.input_value(f"{box} .camera-spec") == "basler:0815-0000"
        page.fill(f"{box} .camera-features", f"TestImageSelector=Off\nImageFileMode=On\nImageFilename={served}")
        page.select_option(f"{box} .camera-trigger", "software")
        page.click(f"{box} .camera-use")
        page.wait_for_function("document.body.dataset.cameraDone", timeout=30000)
        assert page.evaluate("document.body.dataset.cameraDone") == "1", page.inner_text("#video-status")
        assert "camera basler:0815-0000" in page.inner_text("#video-status")
        page.check("#live-dense")            # no edge to track: dense depth every frame
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-frame').textContent) >= 3", timeout=60000)
        page.click("#live-stop")
