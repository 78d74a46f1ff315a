"""End to end in headless Chromium: load a simulated complex image, double-click an edge on the canvas, read the
depth the page shows. Truth: the disc's depth (every rim point is at z); the click lands on the rim's projection."""
import os
from pathlib import Path

import pytest

from tests.web.conftest import DISC, rim_point_px

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]
SCREENSHOT = Path(__file__).resolve().parents[2] / "out" / "ci" / "web_double_click.png"


@pytest.fixture
def page():
    if not CHROMIUM.exists():
        if os.environ.get("CI") == "true":
            pytest.fail("CI: /usr/bin/chromium is missing (.ci/run installs Debian's chromium)")
        pytest.skip("no /usr/bin/chromium (apt-get install chromium)")
    from playwright.sync_api import sync_playwright
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=FLAGS)
        try:
            yield browser.new_page(viewport={"width": 1280, "height": 900})
        finally:
            browser.close()


def test_double_click_shows_depth(page, live_server, disc_source):
    _, rig = disc_source
    page.goto(live_server + "/")
    page.wait_for_selector("body[data-ready='1']", timeout=30000)
    box = page.locator("#image").bounding_box()
    u, v = rim_point_px(rig, "left")                      # the rim's leftmost point in the left view
    page.mouse.dblclick(box["x"] + (u + 0.5) * box["width"] / 640, box["y"] + (v + 0.5) * box["height"] / 480)
    page.wait_for_function("document.getElementById('depth').dataset.mm", timeout=30000)
    shown = page.inner_text("#depth")
    z = float(page.get_attribute("#depth", "data-mm"))
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SCREENSHOT), full_page=True)
    print(f"screenshot: {SCREENSHOT}")
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
