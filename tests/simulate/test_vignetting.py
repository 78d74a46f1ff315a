"""The lens's relative illumination in the renderer: the complex image on the sensor is RI times the sum of
the two views (psvs.simulate.render, psvs.optics.illumination)."""
import numpy as np
import pytest

from psvs.simulate.render import render
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.sensor import IDEAL
from psvs.simulate.textures import Checker, Uniform
from tests.support.scenes import FLAT_LIGHT


def _wall(texture, z_mm=800.0):
    return Scene((SceneObject("rectangle", Pose(np.eye(3), np.array([0.0, 0.0, z_mm])), texture,
                              size_mm=(5000.0, 5000.0)),), FLAT_LIGHT)


def test_a_white_wall_falls_off_as_the_lens_says(small_rig):
    """A white wall lit evenly fills both views with radiance 1: the flat lens gives 1 everywhere, the
    vignetting lens (a2, a4) = (-2, 0) gives 1 - 2 rho^2. By hand at pixel (0, 0) of the 160 x 120 sensor
    (0.04 mm pixels, principal point (79.5, 59.5), f = 11.3 mm): h^2 = 3.18^2 + 2.38^2 = 15.7768 mm^2,
    RI = 1 - 2 * 15.7768 / 11.3^2 = 0.752890; at (79, 59) h^2 = 0.02^2 * 2 = 0.0008 mm^2, RI = 0.999987."""
    rig = small_rig.replace(relative_illumination=(-2.0, 0.0))
    res = render(_wall(Uniform(1.0)), rig, supersample=1, sensor=IDEAL)
    assert res.irradiance[0, 0] == pytest.approx(1 - 2 * 15.7768 / 11.3 ** 2, abs=1e-9)
    assert res.irradiance[59, 79] == pytest.approx(1 - 2 * 0.0008 / 11.3 ** 2, abs=1e-9)
    assert res.irradiance[0, 0] == pytest.approx(0.752890, abs=1e-6)
    assert res.image[0, 0] == round(255 * res.irradiance[0, 0])
    np.testing.assert_allclose(res.left, 1.0, atol=1e-12)        # the views' radiance is the scene's
    np.testing.assert_allclose(res.right, 1.0, atol=1e-12)


def test_the_fall_off_multiplies_whatever_the_scene_is(small_rig):
    """A checkered wall: the vignetted image is exactly RI times the flat lens's image, pixel by pixel."""
    from psvs.optics.illumination import illumination_map
    scene = _wall(Checker(25.0), 700.0)
    rig = small_rig.replace(relative_illumination=(-2.0, -0.8))
    flat = render(scene, small_rig, supersample=2, sensor=IDEAL)
    vig = render(scene, rig, supersample=2, sensor=IDEAL)
    np.testing.assert_allclose(vig.irradiance, flat.irradiance * illumination_map(rig.camera), rtol=0, atol=1e-12)
    assert illumination_map(rig.camera).min() < 0.8
