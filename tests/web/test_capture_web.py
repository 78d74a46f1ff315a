"""The capture assistant in the web UI: its API on a simulated hand-held video (TestClient) until the set is
enough, its refusals, and the page in headless Chromium showing progress and saved views."""
import time

import pytest

from psvs.calibrate.capture import ALL_BINS
from psvs.io.params import load_rig
from psvs.targets.target_file import load_target
from psvs.web.app import create_app
from psvs.web.capture_runner import CaptureSetup
from psvs.web.sources import image_source, video_source
from tests.support.browser import shot
from tests.support.web import local_client, serving


def _app(hand_video, folder):
    setup = CaptureSetup(load_target(hand_video.target), hand_video.target.read_bytes(), str(folder))
    return create_app(video_source(str(hand_video.path)), load_rig("clear"), "clear", setup)


@pytest.mark.slow          # the whole video through the detector
def test_capture_api_until_enough(hand_video, tmp_path):
    """Start on the video (9 views), poll until the set is enough: every bin covered, the files the state names
    are the folder's, target.toml copied, the events the terminal's words."""
    folder = tmp_path / "views"
    with local_client(_app(hand_video, folder)) as c:
        assert c.get("/api/capture/frame.png").status_code == 404
        info = c.get("/api/info").json()["capture"]
        assert info == {"target": "4x6 discs, 7 mm across, 14 mm apart", "folder": str(folder)}
        assert c.post("/api/capture/start", json={"views": 9}).json() == {"running": True}
        # another card or folder is not taken while the set is being captured
        r = c.post("/api/capture/setup", json={"target": hand_video.target.read_text(), "folder": str(tmp_path / "v2")})
        assert r.status_code == 400 and r.json()["detail"] == "stop the capture before choosing another card or folder"
        t0 = time.monotonic()
        while (s := c.get("/api/capture/state").json())["running"] and time.monotonic() - t0 < 300:
            time.sleep(0.2)
        assert s["error"] == "" and s["complete"] and s["saved"] >= 9, s
        assert all(s["covered"][b] >= 1 for b in ALL_BINS) and s["missing"] == ""
        assert sorted(p.name for p in folder.iterdir()) == ["target.toml", *s["names"]]
        assert (folder / "target.toml").read_bytes() == hand_video.target.read_bytes()
        saved = [e for e in s["events"] if ": saved view_" in e]
        assert len(saved) == s["saved"] and saved[0].startswith("frame ") and "(1/9)" in saved[0]
        assert s["events"][-1] == f"enough to calibrate: {s['saved']} views in {folder}"
        assert c.get("/api/capture/frame.png").headers["content-type"] == "image/png"


def test_capture_refusals(hand_video, tmp_path):
    """No card and folder given, a bad count or range, a still image: 4xx, one line; nothing written."""
    folder = tmp_path / "views"
    grey = video_source(str(hand_video.path)).still
    with local_client(create_app(video_source(str(hand_video.path)), load_rig("clear"))) as c:
        r = c.post("/api/capture/start", json={})
        assert r.status_code == 400 and "capture needs a card and a folder: choose them" in r.json()["detail"]
        assert c.get("/api/capture/state").json()["available"] is False
    setup = CaptureSetup(load_target(hand_video.target), b"", str(folder))
    with local_client(create_app(image_source("still", grey), load_rig("clear"), "clear", setup)) as c:
        r = c.post("/api/capture/start", json={})
        assert r.status_code == 400 and "a still image has no live frames" in r.json()["detail"]
        assert c.post("/api/capture/start", json={"views": 1}).status_code == 422
        r = c.post("/api/capture/start", json={"near_mm": 900, "far_mm": 400})
        assert r.status_code == 400 and r.json()["detail"] == "near_mm must be < far_mm, got 900 and 400"
        r = c.post("/api/capture/start", json={"far_mm": 9000})
        assert r.status_code == 400 and "reaches outside the 300-2000 mm" in r.json()["detail"]
    assert not folder.exists()


def test_capture_in_the_page(page, hand_video, tmp_path):
    """The page on the video: start capturing, see the count of saved views rise, the hint, the covered bins and
    the saved files in the events; stop."""
    folder = tmp_path / "views"
    with serving(_app(hand_video, folder)) as url:
        page.goto(url + "/#capture")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        assert "each good pose is saved once into" in page.inner_text("#capture-folder")
        page.fill("#capture-views", "9")
        page.click("#capture-start")
        page.wait_for_function("Number(document.getElementById('capture-saved').dataset.n) >= 2", timeout=120000)
        events = page.inner_text("#capture-events")
        shot(page, "web_capture.png")
        page.click("#capture-stop")
        assert "saved view_00.png (1/9)" in events and "saved view_01.png (2/9)" in events
        assert page.inner_text("#capture-saved").endswith(" / 9")
        assert page.locator("#capture-field td.covered").count() >= 2
        assert page.locator("#capture-depth span.covered").count() >= 1
        assert page.inner_text("#capture-hint") != ""
    assert {"target.toml", "view_00.png", "view_01.png"} <= {p.name for p in folder.iterdir()}
