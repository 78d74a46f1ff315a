"""A ray of one path that meets another mirror's back, or the plate's box, is blocked: the same test
(psvs.optics.solids) in ``psvs design``'s layout check, the ray trace, projection and the renderer."""
import math

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.optics.design import design_mirrors
from psvs.optics.field import field_pixels
from psvs.optics.obstruction import find_obstructions
from psvs.optics.project import project_points
from psvs.optics.rig import MirrorExtent
from psvs.optics.trace import trace_pixels
from psvs.simulate.render import render
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.sensor import IDEAL
from psvs.simulate.textures import Uniform
from tests.support.scenes import FLAT_LIGHT

CENTRE = [[319.5, 239.5]]


def _m2_reaching(s0_mm: float):
    """The paper's rig without a plate (d = 0), M1 unbounded, M2 a rectangle from s = s0 to 30 mm along it.

    By hand (omega_1 = 45 deg, c1 = 22, c2 = 44, b = 100): the right view's central ray goes up the axis to
    M1 at (0, 0, 22) and turns to +X toward M4 at x = 50, along the line z = 22. M2 is the plane z = 44 - x
    with s = (-sin 45, 0, cos 45) from its anchor (0, 0, 44): the line meets it at (22, 0, 22), where
    s = (22, 0, -22) . s = -22 sqrt(2) = -31.113 mm. M2 reaching below that puts its back in the ray."""
    ext = MirrorExtent((s0_mm, 30.0), (-20.0, 20.0))
    return default_rig().replace(plate_thickness_mm=0.0).with_extents({"m2": ext})


@pytest.mark.parametrize("s0_mm, blocked", [(-31.0, False), (-31.2, True), (-40.0, True), (-20.0, False)])
def test_a_mirror_back_in_the_other_path_by_hand(s0_mm, blocked):
    rig = _m2_reaching(s0_mm)
    assert -22 * math.sqrt(2) == pytest.approx(-31.113, abs=1e-3)
    assert trace_pixels(CENTRE, rig, "right").valid[0] == (not blocked)
    assert trace_pixels(CENTRE, rig, "left").valid[0]      # the left view's own M2: not a blocker
    # the point on O2's axis that the central pixel sees: projection says the same
    _, ok = project_points([[50.0, 0.0, 600.0]], rig, "right")
    assert ok[0] == (not blocked)


def test_the_renderer_renders_it_blocked():
    """A white wall evenly lit: where M2's back blocks the right view, only the left view's half of the light
    arrives (split 0.5): the central pixel is 0.5 with M2 reaching -40 mm, 1.0 with it ending at -20 mm."""
    wall = Scene((SceneObject("rectangle", Pose(np.eye(3), np.array([0.0, 0.0, 800.0])), Uniform(1.0),
                              size_mm=(5000.0, 5000.0)),), FLAT_LIGHT)
    rig = _m2_reaching(-40.0).replace(pixel_pitch_mm=(0.04, 0.04), image_size_px=(160, 120),
                                       principal_point_px=(79.5, 59.5))
    res = render(wall, rig, supersample=1, sensor=IDEAL)
    assert res.right[59, 79] == 0.0 and res.left[59, 79] == pytest.approx(1.0, abs=1e-12)
    assert res.irradiance[59, 79] == pytest.approx(0.5, abs=1e-12)
    clear = render(wall, _m2_reaching(-20.0).replace(pixel_pitch_mm=(0.04, 0.04), image_size_px=(160, 120),
                                                     principal_point_px=(79.5, 59.5)), supersample=1, sensor=IDEAL)
    assert clear.irradiance[59, 79] == pytest.approx(1.0, abs=1e-12)


def test_design_and_the_trace_agree_on_a_blocked_layout():
    """misaligned's build with the lens it had before (k2 = 0.11), mirrors sized for its whole field: design
    finds M2 in the left view's light leaving M3 on a share of the field; the trace blocks exactly those
    field rays, and no ray of the right view."""
    rig = load_rig("misaligned")
    rig = rig.replace(distortion=(-0.2, 0.11) + rig.camera.distortion[2:])
    designed = design_mirrors(rig, search=False)
    assert not designed.ok
    (obs,) = designed.obstructions
    assert (obs.blocker, obs.view, obs.segment) == ("M2", "left", "M3 -> scene")
    pixels = field_pixels(designed.rig.camera)
    left = trace_pixels(pixels, designed.rig, "left")
    assert (~left.valid).mean() == pytest.approx(obs.fraction, abs=1e-12)
    assert not trace_pixels([obs.example_px], designed.rig, "left").valid[0]
    assert trace_pixels(pixels, designed.rig, "right").valid.all()
    assert find_obstructions(designed.rig, pixels)[0].fraction == obs.fraction


def test_the_shipped_misaligned_build_is_clear():
    """`psvs design --rig misaligned --no-search`: clear (its lens, k2 = 0.45, keeps M2 at 44 mm in the window)."""
    d = design_mirrors(load_rig("misaligned"), search=False)
    assert d.ok, d.problems
    w, h = d.rig.camera.image_size_px
    v, u = np.mgrid[0:h:7, 0:w:7]
    uv = np.column_stack([u.ravel(), v.ravel()]).astype(float)
    for view in ("left", "right"):       # mirrors of the designed size: every pixel sees the scene
        assert trace_pixels(uv, d.rig, view).valid.all()


@pytest.mark.parametrize("rig_name", ["default", "mv1440"])
def test_no_pixels_trace_to_no_rays(rig_name):
    """An empty set of pixels (a matched edge whose every row a build's view cannot see) traces to empty
    rays, as one pixel's traces to one, with the glass's finite solids (mv1440) or without (a bench's false
    alarm on mv1440 once crashed here)."""
    rig = load_rig(rig_name)
    for view in ("left", "right"):
        rays = trace_pixels(np.zeros((0, 2)), rig, view)
        assert rays.origins_mm.shape == rays.dirs.shape == (0, 3) and rays.valid.shape == (0,)
        one = trace_pixels([[320.0, 240.0]], rig, view)
        assert one.origins_mm.shape == (1, 3) and one.valid.all()
