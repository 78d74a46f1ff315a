"""Planted drift for the refit's tests: a build's mirrors knocked, frames of noise-textured walls and tares
rendered through it, and the depth a point on the axis reads through a rig."""
import math

import numpy as np

from psvs.health.explain import tilted
from psvs.optics.rig import MirrorError
from psvs.simulate.builtin import regulated_light
from psvs.simulate.render import render
from psvs.simulate.scene import Scene
from psvs.simulate.textures import Noise

#: The tares' distances (mm) of :func:`frames_of`.
TARE_MM = (600.0, 950.0)
#: Knocks: (mirror, tilt a deg, tilt b deg, shift mm) each.
DRIFTS = {"m3 and m4 (issue 43)": (("m3", 0.0, 0.06, 0.0), ("m4", 0.05, 0.03, 0.0)),
          "m2 and m1": (("m2", 0.0, -0.08, 0.0), ("m1", 0.04, 0.0, 0.0))}


def wall(z_mm: float, seed: int) -> Scene:
    """A wall of 1.5 mm value noise at ``z_mm``, filling the view."""
    return Scene((), regulated_light(z_mm), z_mm, Noise(scale_mm=1.5, seed=seed), "wall")


def knocked(rig, drift):
    """``rig`` with each of ``drift``'s mirrors turned and shifted ((mirror, a deg, b deg, shift mm), ...)."""
    for m, a, b, s in drift:
        rig = tilted(rig, m, math.radians(a), math.radians(b))
        e = getattr(rig.mirrors, f"{m}_error")
        rig = rig.with_errors({m: MirrorError(e.tilt_rad, e.shift_mm + s)})
    return rig


def frames_of(rig, seed=0):
    """Three walls at 650-1000 mm, and tare walls at TARE_MM ((image, mm) each), through ``rig``."""
    walls = [render(wall(z, seed + k), rig, seed=seed + k).image for k, z in enumerate((650.0, 800.0, 1000.0))]
    return walls, [(render(wall(z, seed + 9 + k), rig, seed=seed + 9 + k).image, z) for k, z in enumerate(TARE_MM)]


def axis_depth(used, truth, z_mm: float) -> float:
    """The depth (mm) a point on the axis at ``z_mm`` (seen through the ``truth`` rig) reads through ``used``."""
    from psvs.measure.triangulate import triangulate
    from psvs.optics.project import project_points
    point = np.array([[0.0, 0.0, z_mm]])
    left, right = project_points(point, truth, "left")[0], project_points(point, truth, "right")[0]
    return float(triangulate(left, right, used, model="exact").points_mm[0, 2])
