"""End to end in headless Chromium: load a simulated complex image, double-click an edge on the canvas, read the
depth the page shows. Truth: the disc's depth (every rim point is at z); the click lands on the rim's projection."""
import os
from pathlib import Path

import pytest

from psvs import default_rig
from psvs.web.app import create_app
from psvs.web.sources import video_source
from tests.live.test_tracker import rim_seed
from tests.web.conftest import DISC, rim_point_px, serving

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]
SHOTS = Path(__file__).resolve().parents[2] / "out" / "ci"


@pytest.fixture
def page():
    if not CHROMIUM.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI: {CHROMIUM} is missing (.ci/run installs Debian's chromium)")
        pytest.skip(f"no {CHROMIUM} (apt-get install chromium)")
    from playwright.sync_api import sync_playwright
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=FLAGS)
        try:
            yield browser.new_page(viewport={"width": 1280, "height": 900})
        finally:
            browser.close()


def shot(page, name: str) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / name), full_page=True)
    print(f"screenshot: {SHOTS / name}")


def dblclick_px(page, u, v):
    """Double-click image pixel (u, v) of the canvas, wherever and however large the page draws it."""
    box = page.locator("#image").bounding_box()
    page.mouse.dblclick(box["x"] + (u + 0.5) * box["width"] / 640, box["y"] + (v + 0.5) * box["height"] / 480)


def test_double_click_shows_depth(page, live_server, disc_source):
    _, rig = disc_source
    page.goto(live_server + "/")
    page.wait_for_selector("body[data-ready='1']", timeout=30000)
    u, v = rim_point_px(rig, "left")                      # the rim's leftmost point in the left view
    dblclick_px(page, u, v)
    page.wait_for_function("document.getElementById('depth').dataset.mm", timeout=30000)
    shown = page.inner_text("#depth")
    z = float(page.get_attribute("#depth", "data-mm"))
    shot(page, "web_double_click.png")
    assert shown.endswith(" mm") and abs(float(shown.split()[0]) - z) < 0.01
    assert abs(z - DISC["z_mm"]) <= 0.01 * DISC["z_mm"]
    assert page.inner_text("#status") == "edge matched"
    assert float(page.inner_text("#disparity").split()[0]) > 0
    # the automatic button pairs the disc with its twin: one row in the table, at the same depth
    page.click("#auto")
    page.wait_for_function("document.getElementById('seed').textContent === 'automatic'", timeout=30000)
    rows = page.locator("#pairs tbody tr")
    assert rows.count() == 1
    assert abs(float(rows.nth(0).locator("td").nth(3).inner_text()) - DISC["z_mm"]) <= 0.01 * DISC["z_mm"]


def test_live_mode_in_the_page(page, disc_video):
    """Serve a simulated video, double-click the disc's rim, start live: the page shows frames, a frame rate
    and each frame's depth (1 % of that frame's truth)."""
    path, truth, rig, scene, positions = disc_video
    with serving(create_app(video_source(str(path)), rig)) as url:
        page.goto(url + "/")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        dblclick_px(page, *rim_seed(rig, scene, positions[0]))
        page.wait_for_function("document.getElementById('depth').dataset.mm", timeout=30000)
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-frame').textContent) >= 15", timeout=30000)
        page.click("#live-stop")
        # read the frame number and its depth in one go (a poll may still be landing)
        frame, z = page.evaluate("() => [Number(document.getElementById('live-frame').textContent), "
                                 "Number(document.getElementById('live-depth').dataset.mm)]")
        assert abs(z - truth[frame % len(truth)]) <= 0.01 * truth[frame % len(truth)]
        assert float(page.inner_text("#live-fps")) > 0 and page.inner_text("#live-latency").endswith(" ms")
        shot(page, "web_live.png")


def test_live_dense_in_the_page(page, wall_video):
    """Tick dense, start live without an edge: the page shows each frame's dense map and median depth (1 % of
    that frame's truth)."""
    path, truth = wall_video
    with serving(create_app(video_source(str(path)), default_rig())) as url:
        page.goto(url + "/")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        page.check("#live-dense")
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-dense-z').dataset.frame) >= 3", timeout=60000)
        page.click("#live-stop")
        frame, z = page.evaluate("() => [Number(document.getElementById('live-dense-z').dataset.frame), "
                                 "Number(document.getElementById('live-dense-z').dataset.mm)]")
        assert abs(z - truth[frame % len(truth)]) <= 0.01 * truth[frame % len(truth)]
        assert page.is_visible("#live-dense-map") and page.inner_text("#live-dense-ms").endswith(" ms")
        page.wait_for_function("document.getElementById('live-dense-map').naturalWidth === 640", timeout=10000)
        shot(page, "web_live_dense.png")
