"""The sweep's renders: the renderer's images as irradiance (before the sensor), with the share of its samples
traced, supersampled only where the image is not smooth when asked (:mod:`psvs.simulate.adaptive`, on its
coarser 4 px grid: the sweep's cards and scenes hold no feature under 9 px)."""
from __future__ import annotations

from psvs.simulate.scene import Scene

#: The renderer's supersampling (``render``'s default: 2 x 2 samples a pixel).
SUPERSAMPLE = 2
#: px: the one-sample pass's coarse grid for the sweep's scenes (a disc of 9 px or more covers one of its points).
SWEEP_STEP_PX = 4


def render_irradiance(scene: Scene, rig, supersample: int = SUPERSAMPLE, adaptive: bool = False):
    """The noiseless irradiance (H, W) of ``scene`` through ``rig``, as ``psvs.simulate.render.render`` gives
    it (``RenderResult.irradiance``: C = RI ((1 - s) L + s R), each view K x K samples a pixel), and the share
    of the renderer's samples it traced; with ``adaptive``, from :func:`psvs.simulate.adaptive.adaptive_views`
    (tests/simulate/test_adaptive.py and tests/dense/test_sweep.py compare both)."""
    from psvs.simulate.adaptive import adaptive_views
    from psvs.simulate.geometry import SceneGeometry
    from psvs.simulate.render import check_scene_in_front, complex_irradiance, render_views
    geom = SceneGeometry(scene)
    if not adaptive:
        left, right = render_views(scene, rig, supersample, geom)
        share = 1.0
    else:
        check_scene_in_front(geom, rig)
        left, right, share = adaptive_views(geom, scene, rig, supersample, SWEEP_STEP_PX)
    return complex_irradiance(left, right, rig), share
