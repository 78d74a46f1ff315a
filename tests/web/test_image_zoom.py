"""The complex image at full resolution, zoomable (issue 44, item 3): the Measure step's button draws the served
image itself as a plotly image (zoom by a dragged box, pan), every pixel of it; a new image hides the old view.
Truth: the served array."""
import base64

import cv2
import numpy as np

from psvs.io.params import load_rig
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.web import serving


def test_the_complex_image_opens_at_full_resolution_zoomable(page):
    grey = np.random.default_rng(3).integers(0, 256, (480, 640)).astype(np.uint8)
    with serving(create_app(image_source("noise", grey), load_rig("default"))) as url:
        page.goto(url + "/#measure")
        page.wait_for_selector("body[data-ready='1']", timeout=60000)
        page.click("#image-zoom-open")
        page.wait_for_function("document.getElementById('image-zoom').dataset.ready === '1'", timeout=60000)
        trace = page.evaluate("(() => { const el = document.getElementById('image-zoom');"
                              " return [el.data[0].type, el.data[0].source, el.layout.dragmode]; })()")
        assert trace[0] == "image" and trace[2] == "zoom"
        png = base64.b64decode(trace[1].split(",", 1)[1])
        shown = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_GRAYSCALE)
        assert np.array_equal(shown, grey)
        assert page.evaluate("document.getElementById('image-zoom').hidden") is False
