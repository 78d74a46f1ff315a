"""The parallel kernels on every core agree with the same kernels on one (the suite's workers run them on
their share of the cores: tests/conftest.py): a race or a thread-dependent reduction would show here."""
import numba
import numpy as np
import pytest

from psvs.dense import DEFAULT, FAST, dense_disparity, separate_views
from psvs.dense.cost import NO_TWIN, filter_volume
from psvs.dense.evaluate import superimpose
from tests.dense.planted import layered_pair


@pytest.fixture
def threads():
    """Run with 1 thread, then with all of Numba's; the test's thread setting is restored after."""
    before = numba.get_num_threads()
    yield [1, numba.config.NUMBA_NUM_THREADS]
    numba.set_num_threads(before)


def test_guided_filter_is_the_same_on_one_and_every_core(threads):
    rng = np.random.default_rng(5)
    vol = rng.uniform(-1, 1, (7, 40, 56)).astype(np.float32)
    vol[3, :, :6] = NO_TWIN
    guide = rng.random((40, 56)).astype(np.float32)
    out = []
    for n in threads:
        numba.set_num_threads(n)
        out.append(filter_volume(vol, guide, 3, 0.01))
    np.testing.assert_array_equal(out[0], out[1])


@pytest.mark.parametrize("params", [DEFAULT, FAST], ids=["default", "fast"])
def test_dense_maps_are_the_same_on_one_and_every_core(threads, params):
    """Both maps of a planted pair, bit for bit: no kernel's sum depends on how the rows are shared out
    (psvs batch's workers run on one thread each, psvs disparity on every core: their maps must agree)."""
    left, right, _, _ = layered_pair()
    image = superimpose(left, right, 0.5)
    maps = []
    for n in threads:
        numba.set_num_threads(n)
        res = dense_disparity(image, 0, 40, params=params)
        maps.append((res.disparity_left, res.disparity_right))
    for a, b in zip(*maps, strict=True):
        np.testing.assert_array_equal(a, b)


def test_view_separation_is_the_same_on_one_and_every_core(threads):
    """The views separated by conjugate gradients (whose dot products are parallel sums), bit for bit."""
    left, right, true_left, true_right = layered_pair()
    image = superimpose(left, right, 0.5)
    views = []
    for n in threads:
        numba.set_num_threads(n)
        views.append(separate_views(image, true_left, 0.5, true_right))
    for a, b in zip(*views, strict=True):
        np.testing.assert_array_equal(a, b)
