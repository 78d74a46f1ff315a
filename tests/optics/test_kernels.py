"""The ray tracer's Numba kernels (psvs.optics.kernels) against independent derivations: undoing the lens's
distortion against OpenCV's iterative undistortPoints (OpenCV 4's undistortPointsIter), and the bounding-box
pre-test of the blocking solids against NumPy's whole-array form, NaN included."""
import cv2
import numpy as np
import pytest

from psvs.optics.solids import segments_hit
from psvs.optics.trace import distort, undistort


def _opencv_undistort(xd, dist, criteria):
    """OpenCV's iterated undistortion of normalised points: OpenCV 4 names it undistortPointsIter, OpenCV 5 folds
    it into undistortPoints(..., criteria=) (CI runs both)."""
    pts = xd.reshape(-1, 1, 2)
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(pts, np.eye(3), dist, None, None, criteria).reshape(-1, 2)
    return cv2.undistortPoints(pts, np.eye(3), dist, criteria=criteria).reshape(-1, 2)


@pytest.mark.parametrize("seed", range(4))
def test_undistort_agrees_with_opencv_and_inverts_distort(seed):
    rng = np.random.default_rng(seed)
    # a datasheet-like barrel lens over a 1/2" sensor's normalised field (|x| up to 0.45)
    dist = (rng.uniform(-0.3, -0.05), rng.uniform(0.0, 0.1), rng.uniform(-2e-3, 2e-3), rng.uniform(-2e-3, 2e-3),
            rng.uniform(-0.03, 0.0))
    xn = rng.uniform(-0.45, 0.45, (2000, 2))
    xd = distort(xn, dist)
    got = undistort(xd, dist)
    np.testing.assert_allclose(got, xn, atol=1e-12)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    ref = _opencv_undistort(xd, np.array(dist), criteria)
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_undistort_keeps_nan_and_reads_any_layout():
    xd = np.array([[0.1, np.nan], [0.2, -0.1], [np.nan, np.nan]])
    dist = (-0.2, 0.05, 1e-3, -1e-3, 0.0)
    got = undistort(xd, dist)
    assert np.isnan(got[0]).all() and np.isnan(got[2]).all() and np.isfinite(got[1]).all()
    # a non-contiguous float32 view gives what its float64 copy gives
    wide = np.zeros((3, 4), dtype=np.float32)
    wide[:, ::2] = [[0.1, 0.2], [0.3, -0.1], [-0.2, 0.25]]
    np.testing.assert_array_equal(undistort(wide[:, ::2], dist),
                                  undistort(np.ascontiguousarray(wide[:, ::2], dtype=np.float64), dist))


def test_the_box_pre_test_keeps_every_segment_numpy_keeps():
    """segments_hit tests exactly only the segments whose bounding box meets the solid's; the kernel's choice
    must lose none that the exact test would block: compare the blocked sets with every segment tested."""
    from psvs.io.params import load_rig
    from psvs.optics.mirrors import mirror_planes
    from psvs.optics.solids import hits_plate, hits_rectangle
    rig = load_rig("mv1440")                       # a design with the mirrors' sizes
    rng = np.random.default_rng(5)
    p0 = rng.uniform([-80, -30, -80], [80, 30, 80], (20000, 3))
    p1 = p0 + rng.normal(0, 60, (20000, 3))
    p0[:50, 1] = np.nan
    planes = mirror_planes(rig)
    for solid, plane in (("M1 plate", "m1"), ("M2", "m2"), ("M3", "m3"), ("M4", "m4")):
        got = segments_hit(p0, p1, solid, rig)
        if solid == "M1 plate":
            every = hits_plate(p0, p1, planes[plane], rig.mirrors.plate_thickness_mm)
        else:
            every = hits_rectangle(p0, p1, planes[plane])
        np.testing.assert_array_equal(got, every)
        assert 20 < got.sum() < len(got) and not got[:50].any(), solid
