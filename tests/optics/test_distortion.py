"""Radial distortion against OpenCV's camera model (an independent implementation)."""
import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.measure.triangulate import triangulate
from psvs.optics.project import project_points
from psvs.optics.trace import distort, undistort
from tests.support.geometry import whole_field_points

K = (-0.25, 0.12)


@pytest.fixture
def rig():
    return default_rig().replace(distortion=(*K, 0.0, 0.0, 0.0))


def test_right_view_matches_opencv_projectpoints(rig):
    """The right view is a pinhole at O2 = (b/2, 0, -b/2): OpenCV with tvec = -O2 and dist (k1, k2, 0, 0)."""
    pts = whole_field_points(rig, n_side=7)
    uv, ok = project_points(pts, rig, "right")
    f_px = 11.3 / 0.01
    K_cv = np.array([[f_px, 0, 319.5], [0, f_px, 239.5], [0, 0, 1.0]])
    ref, _ = cv2.projectPoints(pts, np.zeros(3), -np.array([50.0, 0.0, -50.0]), K_cv, np.array([*K, 0.0, 0.0]))
    assert ok.all()
    np.testing.assert_allclose(uv, ref[:, 0, :], atol=1e-6)


def test_undistort_inverts_distort():
    rng = np.random.default_rng(0)
    xn = rng.uniform(-0.3, 0.3, (1000, 2))
    np.testing.assert_allclose(undistort(distort(xn, K), K), xn, atol=1e-12)


@pytest.mark.parametrize("model", ["paper", "exact"])
def test_triangulation_undistorts(rig, model):
    flat = rig.replace(plate_thickness_mm=0.0) if model == "paper" else rig
    pts = whole_field_points(flat, n_side=5)
    left, _ = project_points(pts, flat, "left")
    right, _ = project_points(pts, flat, "right")
    np.testing.assert_allclose(triangulate(left, right, flat, model=model).points_mm, pts, atol=1e-6)


def test_distortion_moves_field_corners():
    plain, bent = default_rig(), default_rig().replace(distortion=(*K, 0.0, 0.0, 0.0))
    p = [[200.0, 150.0, 700.0]]
    assert np.abs(project_points(p, plain, "right")[0] - project_points(p, bent, "right")[0]).max() > 1.0
