import numpy as np
import pytest

from psvs.simulate.scene import Lighting, Pose, Scene, SceneObject
from psvs.simulate.textures import Uniform

FLAT_LIGHT = Lighting(ambient=1.0, lamp=0.0, shadows=False)


def white_disc_scene(x_mm=-20.0, y_mm=10.0, z_mm=600.0, radius_mm=15.0):
    """A white fronto-parallel disc on a black backdrop, lit evenly: radiance 1 on the disc, 0 elsewhere."""
    disc = SceneObject("disc", Pose(np.eye(3), np.array([x_mm, y_mm, z_mm])), Uniform(1.0), radius_mm=radius_mm)
    return Scene((disc,), FLAT_LIGHT, z_mm + 300, Uniform(0.0))


@pytest.fixture
def small_rig():
    """The default optics on a 160 x 120 sensor with 4x pixels (same field): fast renders."""
    from psvs import default_rig
    return default_rig().replace(pixel_pitch_mm=(0.04, 0.04), image_size_px=(160, 120),
                                 principal_point_px=(79.5, 59.5))
