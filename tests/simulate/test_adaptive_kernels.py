"""The adaptive renderer's two kernels (psvs.simulate.kernels.not_smooth and bilinear_fill) against the NumPy
forms they replaced, written out here: which pixels are not smooth (a NaN among the differences, the frame's
edges, a step, a ramp, noise), and the one-sample pass's interpolation of its coarse grid, bit for bit."""
import numpy as np
import pytest

from psvs.simulate.adaptive import SMOOTH_TOL, grid_cells, rough_pixels
from psvs.simulate.kernels import bilinear_fill


def numpy_rough(img, tol, reach, border):
    """rough_pixels' NumPy form: the largest second difference of four directions (edge pixels repeated)."""
    import cv2
    f = np.pad(img, 1, mode="edge")
    c = f[1:-1, 1:-1]
    d2 = np.zeros_like(c)
    for a, b in (((1, 0), (1, 2)), ((0, 1), (2, 1)), ((0, 0), (2, 2)), ((0, 2), (2, 0))):
        d2 = np.maximum(d2, np.abs(f[a[0]:a[0] + c.shape[0], a[1]:a[1] + c.shape[1]]
                                   + f[b[0]:b[0] + c.shape[0], b[1]:b[1] + c.shape[1]] - 2 * c))
    rough = (d2 > tol).astype(np.uint8)
    if reach == 0:
        return rough.astype(bool)
    if border:
        rough[:reach] = rough[-reach:] = 1
        rough[:, :reach] = rough[:, -reach:] = 1
    return cv2.dilate(rough, np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)).astype(bool)


def images(seed):
    """Smooth and rough images of several shapes: a lamp's fall-off, a step, noise, NaN holes, one row."""
    rng = np.random.default_rng(seed)
    h, w = rng.integers(1, 60), rng.integers(1, 80)
    yy, xx = np.mgrid[:h, :w]
    smooth = 0.5 / (1 + ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / 1e4)
    step = smooth + 0.2 * (xx > w / 3)
    noisy = smooth + rng.normal(0, 3 * SMOOTH_TOL, (h, w))
    holes = noisy.copy()
    holes[rng.random((h, w)) < 0.05] = np.nan
    return smooth, step, noisy, holes


@pytest.mark.parametrize("seed", range(6))
def test_rough_pixels_are_numpys(seed):
    for img in images(seed):
        for reach, border in ((0, False), (0, True), (2, True), (1, False)):
            got = rough_pixels(img, SMOOTH_TOL, reach, border)
            assert np.array_equal(got, numpy_rough(img, SMOOTH_TOL, reach, border)), (img.shape, reach, border)


def test_a_nan_difference_leaves_a_pixel_smooth_as_numpys_maximum_did():
    img = np.zeros((5, 5))
    img[2, 1] = 1.0                              # a step along the row through (2, 2) ...
    img[1, 2] = np.nan                           # ... and a NaN along its column
    assert not rough_pixels(img, reach=0)[2, 2]
    img[1, 2] = 0.0
    assert rough_pixels(img, reach=0)[2, 2]


@pytest.mark.parametrize("step", [2, 3, 5])
def test_bilinear_fill_is_numpys(step):
    rng = np.random.default_rng(step)
    h, w = 37, 53
    ys = np.unique(np.r_[np.arange(0, h, step), h - 1])
    xs = np.unique(np.r_[np.arange(0, w, step), w - 1])
    coarse = rng.random((len(ys), len(xs)))
    rough_cell = rng.random((len(ys) - 1, len(xs) - 1)) < 0.3
    (iy, fy), (ix, fx) = grid_cells(ys, h), grid_cells(xs, w)
    out, traced = np.empty((h, w)), np.empty((h, w), bool)
    bilinear_fill(coarse, iy, ix, fy, fx, rough_cell, out, traced)
    along = coarse[:, ix] * (1 - fx[None, :]) + coarse[:, ix + 1] * fx[None, :]
    assert np.array_equal(out, along[iy] * (1 - fy[:, None]) + along[iy + 1] * fy[:, None])
    assert np.array_equal(traced, rough_cell[iy][:, ix])
    assert np.array_equal(out[np.ix_(ys, xs)], coarse)         # the nodes themselves, exactly
    assert iy[-1] == len(ys) - 2 and fy[-1] == 1.0 and fx[0] == 0.0   # the last pixel: the last cell's far end
