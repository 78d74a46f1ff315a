"""The running-histogram median against scipy.ndimage.median_filter (the exact median)."""
import numpy as np
import pytest
from scipy.ndimage import median_filter as exact

from psvs.dense.median import LEVELS_PER_PX, median_filter


@pytest.mark.parametrize("size, shape, seed", [(11, (60, 90), 0), (5, (17, 16), 1), (3, (40, 33), 2), (11, (8, 30), 3)])
def test_median_matches_scipy_within_half_a_level(size, shape, seed):
    rng = np.random.default_rng(seed)
    d = np.cumsum(rng.normal(0, 2, shape), axis=1) + rng.uniform(0, 1, shape) + 40.0   # streaks and noise
    d[5:9, 10:14] = 3.25                                                              # a plateau
    got = median_filter(d, size)
    np.testing.assert_allclose(got, exact(d, size=size, mode="nearest"), atol=0.5 / LEVELS_PER_PX + 1e-12)


@pytest.mark.parametrize("size", [3, 5])
def test_small_windows_are_the_exact_median_to_float32(size):
    """Windows of 3 and 5 px (OpenCV's medianBlur): scipy's exact median to float32's rounding, on a map of
    disparities up to 600 px with a plateau at the image's edge."""
    rng = np.random.default_rng(size)
    d = rng.uniform(0.0, 600.0, (45, 70))
    d[:6, :6] = 123.456
    got = median_filter(d, size)
    assert got.dtype == np.float64 and got.shape == d.shape
    np.testing.assert_allclose(got, exact(d, size=size, mode="nearest"), rtol=0, atol=600 * 2 ** -23)


def test_values_on_the_grid_are_exact_and_errors_are_named():
    d = np.random.default_rng(4).integers(0, 64 * LEVELS_PER_PX, (30, 40)) / LEVELS_PER_PX - 5.0
    np.testing.assert_array_equal(median_filter(d, 7), exact(d, size=7, mode="nearest"))
    np.testing.assert_array_equal(median_filter(d, 1), d)
    with pytest.raises(ValueError, match="odd"):
        median_filter(d, 4)
    with pytest.raises(ValueError, match="finite"):
        median_filter(np.full((20, 20), np.nan), 3)


@pytest.mark.parametrize("seed", [0, 7])
def test_a_tiny_change_of_one_pixel_moves_only_the_medians_whose_window_holds_it(seed):
    """Values on the absolute grid k / LEVELS_PER_PX: the map's minimum moving by 1e-7 px (as another
    rounding upstream might move it) changes no median outside that pixel's window, and none by a value
    off the grid."""
    rng = np.random.default_rng(seed)
    d = rng.uniform(20.0, 60.0, (40, 50))
    y, x = np.unravel_index(np.argmin(d), d.shape)
    before = median_filter(d, 7)
    d[y, x] += 1e-7
    after = median_filter(d, 7)
    moved = before != after
    moved[max(y - 3, 0):y + 4, max(x - 3, 0):x + 4] = False
    assert not moved.any()
    np.testing.assert_array_equal(np.rint(after * LEVELS_PER_PX), after * LEVELS_PER_PX)


@pytest.mark.parametrize("size", [1, 5, 11])
def test_a_float32_result_is_the_float64_one_rounded(size):
    """``dtype=np.float32`` (the pyramid's final median, its maps kept as float32): the float64 median rounded
    to float32, value for value, also beside NaN rows (finite_median)."""
    from psvs.dense.maps import finite_median
    rng = np.random.default_rng(size)
    d = np.cumsum(rng.normal(0, 1.5, (33, 47)), axis=1) + 200.0
    d[4, :] = np.nan
    d[10:12, 5:9] = np.inf
    got = finite_median(d, size, np.float32)
    want = finite_median(d, size)
    assert got.dtype == np.float32 and want.dtype == np.float64
    np.testing.assert_array_equal(got, want.astype(np.float32))
    assert np.isnan(got[4]).all() and np.isfinite(got[5:]).all()


@pytest.mark.parametrize("shape", [(0, 5), (4, 0), (0, 0)])
@pytest.mark.parametrize("size", [3, 11])
def test_an_empty_map_has_an_empty_median(shape, size):
    """A map without pixels: an empty result of its shape (the compiled median reads no pixel of it)."""
    got = median_filter(np.zeros(shape), size, np.float32)
    assert got.shape == shape and got.dtype == np.float32
