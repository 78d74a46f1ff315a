import numpy as np
import pytest

from psvs.dense import dense_disparity, psnr_db, separate_views
from psvs.dense.evaluate import superimpose
from tests.dense.planted import layered_pair


@pytest.fixture(scope="module")
def pair():
    return layered_pair()


@pytest.mark.parametrize("split", [0.5, 0.3])
def test_views_come_back_with_the_true_disparity(pair, split):
    left, right, tl, tr = pair
    c = superimpose(left, right, split)
    lv, rv = separate_views(c, tl, split, tr)
    assert psnr_db(lv, left) > 29.0 and psnr_db(rv, right) > 29.0
    assert psnr_db(lv, left) > psnr_db(c, left) + 4.0 and psnr_db(rv, right) > psnr_db(c, right) + 4.0
    # and the separated views still add up to the complex image (least squares: within a few grey levels)
    assert np.sqrt(np.mean(((1 - split) * lv + split * rv - c) ** 2)) < 3.0


def test_views_come_back_with_the_estimated_disparity(pair):
    left, right, _, _ = pair
    c = superimpose(left, right)
    res = dense_disparity(c, 0, 40)
    lv, rv = separate_views(c, res.disparity_left, 0.5, res.disparity_right)
    assert psnr_db(lv, left) > 27.5 and psnr_db(rv, right) > 27.5
    assert psnr_db(lv, left) > psnr_db(c, left) + 3.0   # better than calling the mixture a view


def test_psnr_of_known_errors():
    a = np.zeros((10, 10))
    assert psnr_db(a, a) == float("inf")
    assert psnr_db(a + 2.55, a) == pytest.approx(40.0)


@pytest.mark.parametrize("kwargs, message", [
    ({"disparity_left": np.zeros((5, 5))}, "does not match"),
    ({"split": 1.0}, "split"),
])
def test_bad_input_is_named(pair, kwargs, message):
    left, right, tl, _ = pair
    args = {"image": superimpose(left, right), "disparity_left": tl, **kwargs}
    with pytest.raises(ValueError, match=message):
        separate_views(**args)
