import warnings

import numpy as np
import pytest

from psvs.dense import dense_disparity
from psvs.dense.disparity import fill_from_background
from psvs.dense.evaluate import disparity_scores, superimpose
from tests.dense.planted import layered_pair


@pytest.fixture(scope="module")
def pair():
    return layered_pair()   # background 18 px, foreground rectangle 31 px (120 x 160 px)


def _share_correct(d, truth, value):
    """Share of the pixels whose truth is ``value`` that are within 2 px of it."""
    region = truth == value
    return float(np.mean(np.abs(d[region] - value) <= 2))


@pytest.mark.parametrize("split", [0.5, 0.3])
def test_planted_layers_are_recovered(pair, split):
    left, right, tl, tr = pair
    res = dense_disparity(superimpose(left, right, split), 0, 40)
    assert res.disparity_left.dtype == np.float32 and res.disparity_left.shape == left.shape
    for d, truth in ((res.disparity_left, tl), (res.disparity_right, tr)):
        assert _share_correct(d, truth, 31) > 0.8      # the foreground rectangle
        assert _share_correct(d, truth, 18) > 0.95     # the background around it
    s = disparity_scores(res.disparity_left, tl)
    assert s["bad2_pct"] < 8.0 and s["coverage_pct"] == 100.0
    near = np.abs(res.disparity_left - tl) <= 2
    assert np.mean(np.abs(res.disparity_left - tl)[near]) < 0.35   # sub-pixel: correct pixels are close


def test_fast_mode_finds_both_layers(pair):
    left, right, tl, _ = pair
    res = dense_disparity(superimpose(left, right), 0, 40, fast=True)
    assert res.disparity_left.shape == left.shape
    assert _share_correct(res.disparity_left, tl, 31) > 0.7
    assert _share_correct(res.disparity_left, tl, 18) > 0.95
    assert disparity_scores(res.disparity_left, tl)["bad2_pct"] < 10.0


def test_confidence_is_zero_where_filled_and_high_where_owned(pair):
    left, right, tl, _ = pair
    res = dense_disparity(superimpose(left, right), 0, 40)
    c = res.confidence_left
    assert c.min() >= 0 and c.max() <= 1
    good = np.abs(res.disparity_left - tl) <= 1
    assert np.mean(c[good]) > np.mean(c[~good & np.isfinite(tl)])


def test_fill_from_background_takes_the_farther_side():
    d = np.array([[10.0, 0, 0, 30.0, 0, 12.0]])
    keep = np.array([[True, False, False, True, False, True]])
    np.testing.assert_array_equal(fill_from_background(d, keep), [[10, 10, 10, 30, 12, 12]])
    none = fill_from_background(d, np.zeros_like(keep))
    assert np.all(np.isnan(none))


def test_constant_image_gives_all_nan_with_a_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = dense_disparity(np.full((40, 60), 128.0), 0, 20)
    assert any("constant" in str(w.message) for w in caught)
    assert np.all(np.isnan(res.disparity_left)) and np.all(res.confidence_left == 0)


def test_nearly_constant_image_gives_finite_maps_without_a_crash():
    img = np.full((40, 60), 128.0)
    img[20, 30] = 200.0                       # the 1st and 99th percentiles are equal: the guide uses min..max
    res = dense_disparity(img, 0, 20)
    assert res.disparity_left.shape == img.shape and np.isfinite(res.disparity_left).any()
    assert np.all((res.confidence_left >= 0) & (res.confidence_left <= 1))


@pytest.mark.parametrize("image, lo, hi, message", [
    (np.zeros((0, 0)), 0, 10, "empty"),
    (np.zeros((8, 40)), 0, 10, "too small"),
    (np.zeros((40, 60, 3)), 0, 10, "grey"),
    (np.full((40, 60), np.nan), 0, 10, "NaN"),
    (np.random.default_rng(0).random((40, 60)), 0, 60, "wider than the image"),
    (np.random.default_rng(0).random((40, 60)), 20, 10, "empty"),
    (np.random.default_rng(0).random((40, 60)), -5, 10, ">= 0"),
    (np.random.default_rng(0).random((40, 60)), 0, 2, "below 3 px"),
    (np.random.default_rng(0).random((40, 60)), 10.5, 10.9, "no whole-pixel"),
])
def test_bad_input_is_named(image, lo, hi, message):
    with pytest.raises(ValueError, match=message):
        dense_disparity(image, lo, hi)


def test_fast_mode_on_a_narrow_range_falls_back_to_full_resolution(pair):
    left, right, tl, _ = pair
    res = dense_disparity(superimpose(left, right)[:, :60], 0, 5, fast=True)   # 5 px range: 2.5 at half size
    assert res.disparity_left.shape == (200, 60)
    res = dense_disparity(superimpose(left, right), 20.2, 21.8, fast=True)      # 10.1..10.9: no whole px
    assert res.disparity_left.shape == left.shape and np.nanmax(res.disparity_left) <= 21.8


def test_a_kept_workspace_gives_the_same_maps():
    """Volumes reused from call to call (a live loop), over frames of two sizes and both modes: the same maps
    as fresh memory, and the volumes are the kept ones."""
    from psvs.dense.disparity import Workspace
    left, right, _, _ = layered_pair()
    c = superimpose(left, right)
    ws = Workspace()
    for img, fast in ((c, True), (c, False), (c[:, :150], True), (c, True)):
        want = dense_disparity(img, 0, 40, fast=fast)
        got = dense_disparity(img, 0, 40, fast=fast, workspace=ws)
        for a, b in zip((want.disparity_left, want.disparity_right, want.confidence_left),
                        (got.disparity_left, got.disparity_right, got.confidence_left)):
            np.testing.assert_array_equal(a, b)
    kept = ws.array("fused", ws._arrays["fused"].shape)
    assert kept is ws._arrays["fused"] and kept.dtype == np.float32
