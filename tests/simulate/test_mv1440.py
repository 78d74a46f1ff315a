"""The simulator on the machine-vision rigs (1440 x 1080, 3.45 um pixels, 8 mm lens with k1 -0.27, 2 mm BK7
plate splitting 45/55): a planted disc's twins land where psvs.optics.project puts its centre, to < 0.1 px,
over the field and the working range. Rendered through a sensor window around the twins' rows (the same
optics, fewer rows: psvs.optics.window.roi_rig) to keep the renders small."""
import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.optics.window import roi_rig
from psvs.simulate.render import render
from psvs.simulate.sensor import IDEAL
from tests.support.scenes import centroid, white_disc_scene


def _window(rig, point_mm, rows=64):
    """A sensor window of ``rows`` rows centred on both twins of ``point_mm``: (ROI rig, its first row)."""
    v = [project_points([point_mm], rig, view)[0][0, 1] for view in ("left", "right")]
    h = rig.camera.image_size_px[1]
    v0 = int(np.clip(round(np.mean(v) - rows / 2), 0, h - rows))
    return roi_rig(rig, rows, v0)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mv1440", "mv1440_misaligned"])
@pytest.mark.parametrize("x_mm, y_mm, z_mm", [(-20.0, 10.0, 450.0), (90.0, -60.0, 800.0), (-120.0, 150.0, 1150.0)])
def test_twins_land_where_the_optics_project(name, x_mm, y_mm, z_mm):
    """A 2 mm disc (8 px across at 450 mm: the lens bends a larger disc's image unevenly and moves its
    centroid, ~ k1 (r_disc / f)^2 of the field position), 4 x 4 samples a pixel: each view's centroid is the
    projection of its centre within 0.1 px, and so the disparity is the optics' (the twins 140-520 px apart)."""
    rig = load_rig(name)
    win, v0 = _window(rig, [x_mm, y_mm, z_mm])
    res = render(white_disc_scene(x_mm, y_mm, z_mm, radius_mm=2.0), win, supersample=4, sensor=IDEAL)
    found, want = {}, {}
    for view, img in (("left", res.left), ("right", res.right)):
        uv, ok = project_points([[x_mm, y_mm, z_mm]], win, view)
        assert ok[0]
        full, _ = project_points([[x_mm, y_mm, z_mm]], rig, view)
        np.testing.assert_allclose(uv[0] + [0, v0], full[0], atol=1e-6)   # the window is the same optics
        found[view], want[view] = centroid(img, uv[0], half=16), uv[0]
        assert np.abs(found[view] - uv[0]).max() < 0.1, (view, found[view] - uv[0])
    disparity = found["left"][0] - found["right"][0]
    assert disparity == pytest.approx(want["left"][0] - want["right"][0], abs=0.15)
    assert disparity > 130          # the twins far apart (the lens's barrel narrows it toward the field's edge)
    # the complex image on the sensor is the lens's fall-off times the views' split sum
    assert res.irradiance.max() <= 0.55 + 1e-12 and res.irradiance.max() > 0.4
