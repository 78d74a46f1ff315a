import math

import numpy as np
import pytest

from psvs import default_rig
from psvs.optics.mirrors import direction_map, mirror_planes, path, virtual_centre
from psvs.optics.project import project_points


@pytest.mark.parametrize("b, c1, c2", [(100.0, 25.0, 45.0), (60.0, 10.0, 30.0), (250.0, 40.0, 70.0)])
def test_virtual_centres_by_hand(b, c1, c2):
    """By hand (omega_1 = 45 deg): reflecting in x - z = k maps (x, y, z) to (z + k, y, x - k).

    O -> M1 (k = -c1) -> (-c1, 0, c1) -> M4 (k = b/2 - c1) -> (b/2, 0, -b/2) = O2, and
    reflecting in x + z = k maps (x, y, z) to (k - z, y, k - x): O -> M2 (k = c2) -> (c2, 0, c2)
    -> M3 (k = c2 - b/2) -> (-b/2, 0, -b/2) = O1.
    """
    rig = default_rig().replace(baseline_mm=b, m1_axis_distance_mm=c1, m2_axis_distance_mm=c2)
    planes = mirror_planes(rig)
    o = np.zeros((1, 3))
    after_m1 = planes["m1"].reflect_points(o)
    np.testing.assert_allclose(after_m1, [[-c1, 0, c1]], atol=1e-12)
    np.testing.assert_allclose(planes["m4"].reflect_points(after_m1), [[b / 2, 0, -b / 2]], atol=1e-12)
    after_m2 = planes["m2"].reflect_points(o)
    np.testing.assert_allclose(after_m2, [[c2, 0, c2]], atol=1e-12)
    np.testing.assert_allclose(planes["m3"].reflect_points(after_m2), [[-b / 2, 0, -b / 2]], atol=1e-12)
    np.testing.assert_allclose(virtual_centre(rig, "left"), [-b / 2, 0, -b / 2], atol=1e-12)
    np.testing.assert_allclose(virtual_centre(rig, "right"), [b / 2, 0, -b / 2], atol=1e-12)


@pytest.mark.parametrize("angle_deg", [30.0, 40.0, 45.0, 55.0])
def test_virtual_cameras_parallel_at_any_angle(angle_deg):
    """Parallel mirror pairs compose to a pure translation: R = I, centres at (+-b/2, 0, -(b/2) tan w)."""
    rig = default_rig().replace(angle_rad=math.radians(angle_deg))
    for view, sign in (("left", -1), ("right", 1)):
        np.testing.assert_allclose(direction_map(rig, view), np.eye(3), atol=1e-12)
        np.testing.assert_allclose(virtual_centre(rig, view), [sign * 50.0, 0.0, rig.virtual_z_mm], atol=1e-12)
    assert rig.virtual_z_mm == pytest.approx(-50.0 * math.tan(math.radians(angle_deg)), abs=1e-12)


def test_reflecting_twice_is_identity():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(50, 3)) * 100
    for plane in mirror_planes(default_rig()).values():
        np.testing.assert_allclose(plane.reflect_points(plane.reflect_points(p)), p, atol=1e-12)


def test_plus_y_point_projects_to_larger_v(rig):
    """Frame convention: +Y is toward increasing row v, +X toward increasing column u."""
    for view in ("left", "right"):
        uv, ok = project_points([[0, 0, 600.0], [0, 40.0, 600.0], [40.0, 0, 600.0]], rig, view)
        assert ok.all()
        assert uv[1, 1] > uv[0, 1] + 50 and abs(uv[1, 0] - uv[0, 0]) < 1.0
        assert uv[2, 0] > uv[0, 0] + 50


def test_disparity_positive_in_front(rig):
    uv_l, _ = project_points([[0, 0, 600.0]], rig, "left")
    uv_r, _ = project_points([[0, 0, 600.0]], rig, "right")
    assert uv_l[0, 0] - uv_r[0, 0] > 0


def test_path_rejects_unknown_view(rig):
    with pytest.raises(ValueError, match="view must be 'left' or 'right'"):
        path(rig, "middle")


def test_the_virtual_baseline_is_b_on_the_papers_geometry():
    """|O1 O2| = b for omega_1 = 45 deg (O1 = (-b/2, 0, -b/2), O2 = (+b/2, 0, -b/2), paper III.2), any b."""
    from psvs import default_rig
    from psvs.optics.mirrors import virtual_baseline_mm
    for b in (60.0, 100.0, 160.0):
        assert virtual_baseline_mm(default_rig().replace(baseline_mm=b)) == pytest.approx(b, abs=1e-9)


@pytest.mark.parametrize("name", ["default", "mv1440", "mv1440_misaligned"])
def test_a_working_range_cannot_start_inside_the_mirrors(name):
    """Issue 41 (trial s23): --near-mm 30 on the default rig was searched as if a scene could stand there. The
    front of the rig, by hand: on the paper's unbounded geometry the far mirror M3 is anchored at z = c2; a
    designed build's mirrors reach beyond their anchors by half their tilted length."""
    from psvs.io.params import load_rig
    from psvs.optics.mirrors import front_z_mm
    from psvs.optics.search_range import disparity_range
    rig = load_rig(name)
    front = front_z_mm(rig)
    m3 = mirror_planes(rig)["m3"]
    if m3.extent is None:
        assert front == pytest.approx(rig.mirrors.m2_axis_distance_mm, abs=1e-9)
    else:
        assert front > rig.mirrors.m2_axis_distance_mm + 1.0           # the rectangle reaches past its anchor
    lo, hi = disparity_range(rig, front + 1.0, 1200.0)
    assert 0 < lo < hi
    with pytest.raises(ValueError, match=f"near end {front - 1.0:g} mm lies inside the rig: its mirrors reach"):
        disparity_range(rig, front - 1.0, 1200.0)
