import warnings
from dataclasses import replace

import numpy as np
import pytest

from psvs.dense import DEFAULT, FAST, dense_disparity
from psvs.dense.evaluate import disparity_scores, superimpose
from psvs.dense.maps import fill_from_background
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
    res = dense_disparity(superimpose(left, right), 0, 40, params=FAST)
    assert res.disparity_left.shape == left.shape
    assert _share_correct(res.disparity_left, tl, 31) > 0.7
    assert _share_correct(res.disparity_left, tl, 18) > 0.95
    assert disparity_scores(res.disparity_left, tl)["bad2_pct"] < 10.0


@pytest.mark.parametrize("params", [DEFAULT, FAST])
def test_the_callers_image_is_read_never_written(pair, params):
    """A float64 image is searched as it is, not copied (check_image): the caller's array holds the same
    values after the search, and a copy of it gives the same maps."""
    left, right, _, _ = pair
    image = superimpose(left, right)
    before = image.copy()
    res = dense_disparity(image, 0, 40, params=params)
    assert image.dtype == np.float64 and np.array_equal(image, before)
    again = dense_disparity(np.ascontiguousarray(image[:, ::-1][:, ::-1]), 0, 40, params=params)
    assert np.array_equal(res.disparity_left, again.disparity_left, equal_nan=True)


def test_confidence_is_zero_where_filled_and_high_where_owned(pair):
    """Against the planted truth (thresholds from 6 seeds x splits 0.5 and 0.3, with margin: pixels with a
    confidence were within 1 px on 96-98 %, those above 0.5 on 97-99 %; 91-93 % of the pixels had one)."""
    left, right, tl, tr = pair
    res = dense_disparity(superimpose(left, right), 0, 40)
    c = res.confidence_left
    assert c.min() >= 0 and c.max() <= 1
    good = np.abs(res.disparity_left - tl) <= 1
    assert np.mean(c[good]) > np.mean(c[~good & np.isfinite(tl)])
    assert np.all(c[np.isnan(tl)] == 0)        # a twin outside the image (x < d): no evidence, filled
    for d, conf, truth in ((res.disparity_left, c, tl), (res.disparity_right, res.confidence_right, tr)):
        seen = np.isfinite(truth)
        right_px = np.abs(d - truth) <= 1
        owned = (conf > 0) & seen
        assert owned.mean() > 0.85                          # most pixels carry their own evidence ...
        assert np.mean(right_px[owned]) > 0.93              # ... and those are right within 1 px
        assert np.mean(right_px[(conf > 0.5) & seen]) > 0.95
        assert np.mean(conf[right_px & seen]) > 0.5         # high where right


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


@pytest.mark.parametrize("d, y, x", [(5, 10, 45), (12, 20, 30), (15, 30, 20)])
def test_nearly_constant_image_gives_finite_maps_without_a_crash(d, y, x):
    """A flat image with one bright point seen by both views: its left-view copy at x and its right-view
    copy at x - d, two pixels of 2400, so the 1st and 99th percentiles are equal and the guide uses
    min..max. The maps are finite, and the point's disparity d is found where it is seen (measured: within
    0.7 px at d = 5, 8, 12, 15 px and three places each)."""
    img = np.full((40, 60), 128.0)
    img[y, x] = img[y, x - d] = 200.0
    assert np.percentile(img, 1) == np.percentile(img, 99)
    res = dense_disparity(img, 0, 20)
    assert res.disparity_left.shape == img.shape and np.isfinite(res.disparity_left).any()
    assert np.all((res.confidence_left >= 0) & (res.confidence_left <= 1))
    assert abs(res.disparity_left[y, x] - d) <= 1           # the left view's copy, at its own pixel
    assert abs(res.disparity_right[y, x - d] - d) <= 1      # the right view's copy, at its own pixel


@pytest.mark.parametrize("image, lo, hi, message", [
    (np.zeros((0, 0)), 0, 10, "empty"),
    (np.zeros((8, 40)), 0, 10, "too small"),
    (np.zeros((40, 60, 3)), 0, 10, "grey"),
    (np.full((40, 60), np.nan), 0, 10, "NaN"),
    (np.random.default_rng(0).random((40, 60)), 0, 60, "wider than the image"),
    (np.random.default_rng(0).random((40, 60)), 20, 10, "empty"),
    (np.random.default_rng(0).random((40, 60)), -5, 10, ">= 0"),
    (np.random.default_rng(0).random((40, 60)), 0, 2, "below 3 px"),
])
def test_bad_input_is_named(image, lo, hi, message):
    with pytest.raises(ValueError, match=message):
        dense_disparity(image, lo, hi)


def test_the_mode_is_a_set_of_parameters():
    """params= takes a DenseParams (the presets or one's own); None or a flag is refused by name, and there
    is no second way (fast=) to choose the mode."""
    img = np.random.default_rng(0).random((40, 60))
    for bad in (None, True, "fast"):
        with pytest.raises(TypeError, match="params must be a DenseParams"):
            dense_disparity(img, 0, 20, params=bad)
    with pytest.raises(TypeError):
        dense_disparity(img, 0, 20, fast=True)   # the keyword is gone on purpose
    own = dense_disparity(img, 0, 20, params=replace(FAST, n_paths=8))
    assert own.disparity_left.shape == img.shape


def test_widened_keeps_the_pruned_range_inside_the_range_asked_for():
    from psvs.dense.prune import MIN_PRUNED_LAGS, widened, worth_pruning
    assert widened(10.0, 30.0, 0.0, 100.0) == (10.0, 30.0)                   # wide enough: unchanged
    assert widened(20.0, 22.0, 0.0, 100.0) == (17.0, 25.0)                   # about its middle
    assert widened(28.0, 32.0, 0.0, 32.0) == (32.0 - MIN_PRUNED_LAGS, 32.0)  # shifted back inside
    assert widened(0.0, 2.0, 0.0, 100.0) == (0.0, MIN_PRUNED_LAGS)
    assert worth_pruning(0, 3 + 2 * MIN_PRUNED_LAGS + 1) and not worth_pruning(0, 3 + 2 * MIN_PRUNED_LAGS)


def test_fast_mode_on_a_narrow_range_falls_back_to_full_resolution(pair):
    """Ranges with no whole px to search at half size are searched at full resolution, in full-resolution
    px: planted layers inside the range are recovered (thresholds from 6 seeds and two rectangles, with
    margin: 90-95 % of the 3 px layer and 96-99.5 % of the 5 px layer within 1 px; the 21 px plane always)."""
    left, right, tl, _ = pair
    res = dense_disparity(superimpose(left, right)[:, :60], 0, 5, params=FAST)   # 5 px range: 2.5 at half size
    assert res.disparity_left.shape == (200, 60)
    res = dense_disparity(superimpose(left, right), 20.2, 21.8, params=FAST)      # 10.1..10.9: no whole px
    assert res.disparity_left.shape == left.shape and np.nanmax(res.disparity_left) <= 23.0
    assert res.searched_px == (19.0, 23.0) and res.asked_px == (20.2, 21.8)       # a lag beyond each end
    # the same ranges on scenes whose truth lies inside them
    left, right, tl, tr = layered_pair(d_bg=3, d_fg=5, rect=(60, 140, 15, 45))
    res = dense_disparity(superimpose(left, right)[:, :60], 0, 5, params=FAST)
    assert res.searched_px == (3.0, 6.0)
    for d, truth in ((res.disparity_left, tl[:, :60]), (res.disparity_right, tr[:, :60])):
        assert np.mean(np.abs(d[truth == 3] - 3) <= 1) > 0.85     # the background (answers >= 3: not 5)
        assert np.mean(np.abs(d[truth == 5] - 5) <= 1) > 0.9      # the rectangle (not 3)
    left, right, tl, tr = layered_pair(d_bg=21, d_fg=21)
    res = dense_disparity(superimpose(left, right), 20.2, 21.8, params=FAST)
    seen = np.isfinite(tl)
    assert np.mean(np.abs(res.disparity_left[seen] - tl[seen]) <= 1) > 0.99
    assert np.mean(np.abs(res.disparity_right - tr) <= 1) > 0.99


def test_a_kept_workspace_gives_the_same_maps():
    """Volumes reused from call to call (a live loop), over frames of two sizes, two ranges and both modes:
    the same maps as fresh memory, and the volumes are the kept ones (a smaller one inside a larger)."""
    from psvs.dense.workspace import Workspace
    left, right, _, _ = layered_pair()
    c = superimpose(left, right)
    ws = Workspace()
    for img, params, hi in ((c, FAST, 40), (c, DEFAULT, 40), (c[:, :150], FAST, 40), (c, DEFAULT, 30), (c, FAST, 40)):
        want = dense_disparity(img, 0, hi, params=params)
        got = dense_disparity(img, 0, hi, params=params, workspace=ws)
        for a, b in zip((want.disparity_left, want.disparity_right, want.confidence_left),
                        (got.disparity_left, got.disparity_right, got.confidence_left), strict=True):
            np.testing.assert_array_equal(a, b)
    kept = {name: buf for name, buf in ws._buffers.items()}       # what the calls left in the workspace
    assert set(kept) == {"echo", "costs", "sgm"} and ws.coarse._buffers
    dense_disparity(c, 0, 30, workspace=ws)                         # a smaller search: the same memory
    assert all(ws._buffers[name] is buf for name, buf in kept.items())
    small = ws.array("costs", (5, 20, 8))
    assert small.dtype == np.float32 and small.flags.c_contiguous and np.shares_memory(small, kept["costs"])


def test_pruned_range_keeps_the_supported_disparities_with_a_margin():
    """The coarse pass's consistent answers set the range; a few stray ones and filled pixels do not."""
    from psvs.dense.disparity import DenseResult
    from psvs.dense.prune import PRUNE_MARGIN_PX, PRUNE_MARGIN_SHARE, pruned_range
    rng = np.random.default_rng(3)
    d = np.where(rng.random((100, 200)) < 0.5, 20.0, 30.0).astype(np.float32)
    d[0, :5] = 90.0                                   # 5 stray pixels: below the support
    conf = np.ones_like(d)
    filled = np.full_like(d, 120.0)                   # the right map: all filled (confidence 0)
    res = DenseResult(d, filled, conf, np.zeros_like(d), (0.0, 150.0))
    lo, hi = pruned_range(res, 0.0, 150.0, d.size)
    margin = PRUNE_MARGIN_PX + PRUNE_MARGIN_SHARE * 12   # support counts answers within 1 px: 19..31
    assert (lo, hi) == pytest.approx((19 - margin, 31 + margin))
    assert pruned_range(res, 18.0, 31.0, d.size) == (18.0, 31.0)            # never wider than asked
    none = DenseResult(d, d, np.zeros_like(d), np.zeros_like(d), (0.0, 150.0))
    assert pruned_range(none, 0.0, 150.0, d.size) == (0.0, 150.0)          # nothing found: the whole range


def test_a_wide_range_is_pruned_to_the_scene_and_gives_the_same_maps(pair):
    """Layers at 18 and 31 px searched over 0..120 px: the coarse pass narrows the search to about 12..38,
    and the maps are as good as those of the whole search."""
    left, right, tl, tr = pair
    c = superimpose(left, right)
    wide = dense_disparity(c, 0, 120)
    lo, hi = wide.searched_px
    assert 8 <= lo <= 17 and 32 <= hi <= 42
    for d, truth in ((wide.disparity_left, tl), (wide.disparity_right, tr)):
        assert _share_correct(d, truth, 31) > 0.8 and _share_correct(d, truth, 18) > 0.95
    whole = dense_disparity(c, 0, 120, params=replace(DEFAULT, prune=False))
    assert whole.searched_px == (3.0, 121.0)                 # a lag beyond the asked end
    bad2 = lambda d: disparity_scores(d, tl)["bad2_pct"]  # noqa: E731
    assert bad2(wide.disparity_left) <= bad2(whole.disparity_left) + 0.5


@pytest.mark.parametrize("side", [40, 64])
def test_pruning_keeps_a_small_object_whose_disparity_stands_apart(side):
    """A side x side px object at 40 px before a background at 12 px, searched over 0..100: the coarse pass
    finds the object, so the pruned search covers it and recovers it as the whole search does."""
    left, right, tl, _ = layered_pair(d_bg=12, d_fg=40, rect=(100 - side // 2, 100 + side // 2,
                                                               160 - side // 2, 160 + side // 2))
    c = superimpose(left, right)
    pruned = dense_disparity(c, 0, 100)
    whole = dense_disparity(c, 0, 100, params=replace(DEFAULT, prune=False))
    lo, hi = pruned.searched_px
    assert lo <= 10 and 44 <= hi <= 60
    fg = tl == 40
    share = lambda d: float(np.mean(np.abs(d[fg] - 40) <= 2))  # noqa: E731
    assert share(pruned.disparity_left) >= share(whole.disparity_left) - 0.02
    assert share(pruned.disparity_left) > (0.3 if side == 40 else 0.6)


def test_one_depth_at_the_end_of_the_range_is_widened_not_searched_whole():
    """A single plane at 30 px searched over 0..32: the pruned range, clipped at 32, is widened inside the
    range to at least MIN_PRUNED_LAGS px instead of falling back to the whole range (and searched a lag beyond
    each of its ends: psvs.dense.params.searched_lags)."""
    from psvs.dense.prune import MIN_PRUNED_LAGS
    left, right, tl, _ = layered_pair(d_bg=30, d_fg=30)
    res = dense_disparity(superimpose(left, right), 0, 32)
    lo, hi = res.searched_px
    assert hi == 33 and MIN_PRUNED_LAGS + 1 <= hi - lo <= 14
    seen = np.isfinite(tl)
    assert np.mean(np.abs(res.disparity_left[seen] - 30) <= 2) > 0.9


def test_a_range_between_two_whole_px_is_searched_on_the_lags_either_side():
    """A range that holds no whole px (20.55..20.95) was refused ('holds no whole-pixel disparity'), though the
    search reads a lag beyond each end (19..22): a plane at 21 px, 0.05 px past the range's end (within the
    trusted tolerance), is now measured; any range from 3 px up leaves at least 2 lags."""
    left, right, tl, tr = layered_pair(d_bg=21, d_fg=21)
    res = dense_disparity(superimpose(left, right), 20.55, 20.95)
    assert res.searched_px == (19.0, 22.0) and res.asked_px == (20.55, 20.95)
    seen = np.isfinite(tl)
    assert np.mean(np.abs(res.disparity_left[seen] - tl[seen]) <= 1) > 0.99
