"""The browser tests' Chromium: the ``page`` fixture (a pytest plugin of the root conftest, so every test
file sees it without importing it), and screenshots and clicks in image pixels.

Debian's ``chromium`` driven by playwright; missing, a test skips with the hint, and fails under CI
(``CI=true``), where .ci/run installs it."""
import os
from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]
#: WebGL (the 3-D views: plotly.js) on the CPU, as headless Chromium has no GPU here
WEBGL_FLAGS = [f for f in FLAGS if f != "--disable-gpu"] + ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
#: where screenshots go (out/ci, kept by CI as artefacts)
SHOTS = Path(__file__).resolve().parents[2] / "out" / "ci"


def _page(flags):
    if not CHROMIUM.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI: {CHROMIUM} is missing (.ci/run installs Debian's chromium)")
        pytest.skip(f"no {CHROMIUM} (apt-get install chromium)")
    from playwright.sync_api import sync_playwright
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=flags)
        try:
            yield browser.new_page(viewport={"width": 1280, "height": 900})
        finally:
            browser.close()


@pytest.fixture
def page():
    """A 1280x900 page of a fresh headless Chromium, closed after the test."""
    yield from _page(FLAGS)


@pytest.fixture
def webgl_page():
    """:func:`page` with WebGL (SwiftShader, on the CPU)."""
    yield from _page(WEBGL_FLAGS)


def shot(page, name: str) -> None:
    """A full-page screenshot ``out/ci/NAME``."""
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / name), full_page=True)
    print(f"screenshot: {SHOTS / name}")


def dblclick_px(page, u, v):
    """Double-click image pixel (u, v) of the canvas, wherever and however large the page draws it."""
    box = page.locator("#image").bounding_box()
    page.mouse.dblclick(box["x"] + (u + 0.5) * box["width"] / 640, box["y"] + (v + 0.5) * box["height"] / 480)
