"""A misaligned build (mirror tilts and shifts, box rotation, OpenCV's full lens model) against an
independent model (tests/reference_build.py: hand-written reflections, OpenCV's lens)."""
import math

import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.measure.triangulate import triangulate
from psvs.optics.mirrors import virtual_centre
from psvs.optics.project import in_image, project_points
from psvs.optics.rig import MirrorError
from psvs.optics.trace import distort, undistort
from tests.support.geometry import whole_field_points
from tests.support.rig_draws import DIST, random_build


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_right_view_matches_the_reference(seed):
    rig, ref = random_build(seed)
    pts = whole_field_points(default_rig(), n_side=6)
    uv, ok = project_points(pts, rig, "right")
    assert ok.all()
    np.testing.assert_allclose(uv, ref.project_right(pts), atol=1e-6)


@pytest.mark.parametrize("seed", [0, 3])
def test_left_view_matches_the_reference(seed):
    rig, ref = random_build(seed)
    pts = whole_field_points(default_rig(), n_side=4, depths=(450.0, 800.0, 1150.0))
    uv, ok = project_points(pts, rig, "left")
    assert ok.all()
    want = np.array([ref.project_left(p) for p in pts])
    np.testing.assert_allclose(uv, want, atol=1e-6)


@pytest.mark.parametrize("seed", [0, 4])
def test_exact_triangulation_inverts_projection_on_a_build(seed):
    rig, _ = random_build(seed)
    pts = whole_field_points(default_rig(), n_side=7)
    left, okl = project_points(pts, rig, "left")
    right, okr = project_points(pts, rig, "right")
    seen = in_image(left, rig) & in_image(right, rig)      # the build's lens and centre move some off the sensor
    res = triangulate(left, right, rig, model="exact")
    assert seen.mean() > 0.5 and (okl & okr)[seen].all() and np.array_equal(res.valid, seen)
    np.testing.assert_allclose(res.points_mm[seen], pts[seen], atol=1e-6)
    assert np.isnan(res.points_mm[~seen]).all()


def test_a_build_breaks_the_rows_and_the_nominal_model():
    """What a realistic build does: twins up to 12-20 px apart vertically somewhere in the field (here: a
    reasoned bound of > 3 px), and the nominal rig, fed the true correspondences, off by tens of mm
    (> 10 mm mean) -- while the build's own model is exact (test above)."""
    rig, _ = random_build(0)
    pts = whole_field_points(default_rig(), n_side=7)
    left, _ = project_points(pts, rig, "left")
    right, _ = project_points(pts, rig, "right")
    seen = in_image(left, rig) & in_image(right, rig)
    assert np.nanmax(np.abs(left[seen, 1] - right[seen, 1])) > 3.0
    nominal = triangulate(left[seen], right[seen], default_rig(), model="exact").points_mm
    assert np.nanmean(np.linalg.norm(nominal - pts[seen], axis=1)) > 10.0


def test_errors_move_the_virtual_centres_as_reflections_do():
    """A shift s of M4 along its normal moves O2 by 2 s along that normal (reflection in a moved plane);
    M1 at its anchor turned by a about Y moves O2 by the rotation of O's image about the anchor (by 2a)."""
    s = 0.5
    moved = default_rig().with_errors({"m4": MirrorError((0.0, 0.0), s)})
    n4 = np.array([-1.0, 0.0, 1.0]) / math.sqrt(2)
    np.testing.assert_allclose(virtual_centre(moved, "right") - virtual_centre(default_rig(), "right"),
                               2 * s * n4, atol=1e-12)
    a = math.radians(0.3)
    turned = default_rig().with_errors({"m1": MirrorError((a, 0.0), 0.0)})
    c1 = default_rig().mirrors.m1_axis_distance_mm
    # O's image in M1 is (-c1, 0, c1)... in the designed M1 (z = x + c1): O -> (-c1, 0, c1)
    img = np.array([-c1, 0.0, c1])
    anchor = np.array([0.0, 0.0, c1])
    Ry = cv2.Rodrigues(np.array([0.0, 2 * a, 0.0]))[0]
    new_img = anchor + Ry @ (img - anchor)
    # then M4 (unchanged) reflects it: z = x + c1 - b/2, normal n4
    p4 = np.array([50.0, 0.0, c1])
    want = new_img - 2 * ((new_img - p4) @ n4) * n4
    np.testing.assert_allclose(virtual_centre(turned, "right"), want, atol=1e-9)


def test_full_distortion_matches_opencv_and_inverts():
    rng = np.random.default_rng(0)
    xn = rng.uniform(-0.3, 0.3, (500, 2))
    pts = np.column_stack([xn, np.ones(len(xn))])
    ref, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), np.eye(3), np.array(DIST))
    np.testing.assert_allclose(distort(xn, DIST), ref.reshape(-1, 2), atol=1e-12)
    np.testing.assert_allclose(undistort(distort(xn, DIST), DIST), xn, atol=1e-12)
