import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.measure.equations import project_eq9_10
from psvs.measure.triangulate import triangulate
from psvs.optics.project import epipolar_curve_px, in_image, project_points
from psvs.optics.rig import MirrorExtent
from psvs.optics.trace import trace_pixels
from tests.support.geometry import whole_field_points


def test_projection_matches_independent_model(rig, reference):
    """Exact projection agrees with the reference model (plate formula + unfolding + fsolve)."""
    pts = whole_field_points(rig, n_side=5)
    uv_l, ok_l = project_points(pts, rig, "left")
    uv_r, ok_r = project_points(pts, rig, "right")
    assert ok_l.all() and ok_r.all()
    ref_l = np.array([reference.project_left(p) for p in pts])
    ref_r = np.array([reference.project_right(p) for p in pts])
    np.testing.assert_allclose(uv_l, ref_l, atol=1e-8)
    np.testing.assert_allclose(uv_r, ref_r, atol=1e-8)


def test_projected_pixel_ray_passes_through_point(rig):
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-150, 150, 300), rng.uniform(-100, 100, 300), rng.uniform(300, 2000, 300)])
    for view in ("left", "right"):
        uv, ok = project_points(pts, rig, view)
        assert ok.all()
        rays = trace_pixels(uv, rig, view)
        dist = np.linalg.norm(np.cross(pts - rays.origins_mm, rays.dirs), axis=1)
        assert dist.max() < 1e-9


def test_left_rows_differ_from_right_rows_with_a_plate(rig):
    """The plate also shifts rays vertically off the middle row: y_l != y_r by a fraction of a pixel."""
    uv_l, _ = project_points([[0.0, 100.0, 450.0]], rig, "left")
    uv_r, _ = project_points([[0.0, 100.0, 450.0]], rig, "right")
    assert 0.05 < abs(uv_l[0, 1] - uv_r[0, 1]) < 1.0


def test_zero_plate_left_view_is_pinhole_at_o1(rig):
    """With d = 0 both views are the paper's ideal pinholes (eqs. 9-10)."""
    flat = rig.replace(plate_thickness_mm=0.0)
    pts = whole_field_points(flat, n_side=7)
    xl, xr, y = project_eq9_10(pts, 11.3, 100.0)
    uv_l, _ = project_points(pts, flat, "left")
    uv_r, _ = project_points(pts, flat, "right")
    np.testing.assert_allclose(uv_l, np.column_stack([xl / 0.01 + 319.5, y / 0.01 + 239.5]), atol=1e-9)
    np.testing.assert_allclose(uv_r, np.column_stack([xr / 0.01 + 319.5, y / 0.01 + 239.5]), atol=1e-9)


def test_invalid_points_are_flagged_not_raised(rig):
    uv, ok = project_points([[np.nan, 0, 500], [0, 0, -500.0], [0, 0, 500]], rig, "left")
    assert ok.tolist() == [False, False, True]
    assert np.isnan(uv[:2]).all()


def test_small_mirror_vignettes(rig):
    tiny = rig.with_extents({"m4": MirrorExtent((-1.0, 1.0), (-1.0, 1.0))})
    uv, ok = project_points([[50.0, 0.0, 500.0], [150.0, 0.0, 500.0]], tiny, "right")
    assert ok.tolist() == [True, False]


def test_in_image(rig):
    assert in_image([[0, 0], [639.5, 479.5], [-0.6, 10], [10, 480.0], [np.nan, 1]], rig).tolist() == \
        [True, True, False, False, False]


def test_bad_shapes_raise(rig):
    with pytest.raises(ValueError, match=r"points_mm must have shape \(N, 3\), got \(2, 2\)"):
        project_points(np.zeros((2, 2)), rig, "left")
    with pytest.raises(TypeError, match="points_mm must be a numeric array"):
        project_points([["a", "b", "c"]], rig, "left")


@pytest.mark.parametrize("rig_name", ["default", "misaligned", "mv1440_misaligned"])
def test_an_epipolar_curve_triangulates_back_to_its_depths(rig_name):
    """Each point of a left pixel's epipolar curve, triangulated exactly with that pixel, lies at the depth it
    was drawn at (the ray's point at that z), on the ideal rig and on two builds."""
    rig = load_rig(rig_name)
    w, h = rig.camera.image_size_px
    px = np.array([[0.6 * w, 0.3 * h], [0.8 * w, 0.7 * h]])
    rays = trace_pixels(px, rig, "left")
    z = np.linspace(450.0, 1150.0, 8)
    for k in range(len(px)):
        uv = epipolar_curve_px(rays.origins_mm[k], rays.dirs[k], z, rig)
        assert len(uv) == len(z)
        got = triangulate(np.repeat(px[k:k + 1], len(uv), axis=0), uv, rig, model="exact").points_mm[:, 2]
        np.testing.assert_allclose(got, z, atol=1e-6)
