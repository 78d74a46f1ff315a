import numpy as np
import pytest

from psvs.dense.cost import (
    NO_TWIN,
    PAD_COST,
    aperture_weight,
    band_pass,
    echo_at_winner,
    echo_correlation,
    filter_volume,
    fused_cost,
    order_keys,
)
from tests.dense.planted import texture


def direct_ncc(f, y, x, d, r):
    """NCC of the (2r+1)^2 windows at (y, x) and (y, x - d), rows clamped at the image edge and columns
    clamped to x >= d (where the twin exists), straight from the definition."""
    h, w = f.shape
    ys = np.clip(np.arange(y - r, y + r + 1), 0, h - 1)
    xa = np.clip(np.arange(x - r, x + r + 1), 0, w - 1)
    xb = np.clip(np.arange(x - r, x + r + 1), d, w - 1)
    a, b = f[np.ix_(ys, xa)], f[np.ix_(ys, xb - d)]
    ab = f[np.ix_(ys, xb)] * b
    mu_a, mu_b = a.mean(), f[np.ix_(ys, np.clip(np.arange(x - d - r, x - d + r + 1), 0, w - 1))].mean()
    sd_a = np.sqrt((a * a).mean() - mu_a ** 2)
    bb = f[np.ix_(ys, np.clip(np.arange(x - d - r, x - d + r + 1), 0, w - 1))]
    sd_b = np.sqrt((bb * bb).mean() - mu_b ** 2)
    return (ab.mean() - mu_a * mu_b) / (sd_a * sd_b)


def test_echo_correlation_matches_the_definition():
    rng = np.random.default_rng(3)
    f = rng.random((24, 40)).astype(np.float32)
    lags = np.array([2, 5, 9])
    vol = echo_correlation(f, lags, window=5)
    assert vol.shape == (3, 24, 40)
    for k, d in enumerate(lags):
        assert np.all(vol[k, :, :d] == NO_TWIN)
        for y, x in ((0, d), (7, 20), (23, 39), (12, d + 1)):
            assert vol[k, y, x] == pytest.approx(direct_ncc(f, y, x, d, 2), abs=2e-5)


def test_integer_keys_order_as_the_floats_and_turn_back():
    """The echo's maxima run on int32 keys of the float32 bits: ascending floats (negative, both zeros,
    tiny and huge) give ascending keys, and the same map turns the keys back into the floats."""
    v = np.array([-3e38, -1.0, -0.5, -1e-30, -0.0, 0.0, 1e-30, 0.25, 1.0, 3e38], np.float32)
    keys = v.copy().view(np.int32)
    order_keys(keys)
    assert np.all(np.diff(keys.astype(np.int64)) > 0)
    order_keys(keys)
    assert np.array_equal(keys.view(np.float32), v) and np.signbit(keys.view(np.float32)[4])


def test_shiftable_windows_take_the_neighbourhood_maximum_and_short_rows_work():
    """shift_window 5: each pixel's echo is the plain echo's maximum over its 5 x 5 neighbourhood (rows
    inside the image, columns where the twin is); lags that leave rows shorter than the window too."""
    rng = np.random.default_rng(4)
    f = rng.random((20, 30)).astype(np.float32)
    lags = np.array([2, 7, 27, 29])                      # twin rows of 28, 23, 3 and 1 px
    plain = echo_correlation(f, lags, window=5)
    shift = echo_correlation(f, lags, window=5, shift_window=5)
    h, w = f.shape
    for k, d in enumerate(lags):
        assert np.all(shift[k, :, :d] == NO_TWIN)
        for y in range(h):
            for x in range(d, w):
                assert plain[k, y, x] == pytest.approx(direct_ncc(f, y, x, d, 2), abs=2e-5)
                want = plain[k, max(0, y - 2):y + 3, max(d, x - 2):x + 3].max()
                assert shift[k, y, x] == pytest.approx(want, abs=1e-6)


def test_echo_peaks_at_the_planted_disparity():
    # L(x) = t(x), R(x) = t(x + d) = L(x + d): every left-view patch repeats d px to its left. The other
    # view's texture in each window halves the correlation, so a window needs a few hundred pixels.
    t = texture(60, 160, seed=2)
    d = 17
    c = 0.5 * t[:, 0:120] + 0.5 * t[:, d:d + 120]
    lags = np.arange(3, 40)
    vol = echo_correlation(band_pass(c, 0.7), lags, window=21)
    best = lags[np.argmax(vol[:, 10:50, 45:], axis=0)]
    assert np.mean(best == d) > 0.93
    assert np.median(vol[d - 3, 10:50, 45:]) == pytest.approx(0.5, abs=0.1)  # half the window is the twin


def test_fused_cost_takes_either_end_of_a_pair():
    echo = np.full((2, 1, 10), -1.0, np.float32)
    echo[1, 0, 7] = 0.8            # the patch at x = 7 repeats at 7 - 4 = 3
    lags = np.array([2, 4])
    cost = fused_cost(echo, lags)
    assert cost[0, 7, 1] == 0.0 and cost[0, 7, 0] == pytest.approx(1.8)   # left-view end
    assert cost[0, 3, 1] == 0.0 and cost[0, 3, 0] == pytest.approx(1.8)   # right-view end, seen forward
    assert cost.shape == (1, 10, 8) and np.all(cost[..., 2:] == PAD_COST)  # padded to whole vectors


def test_winner_finds_the_parabola_vertex_and_the_echo_is_read_at_it():
    from psvs.dense.sgm import winner
    lags = np.array([10, 11, 12, 13, 14])
    d_true = 12.3
    agg = ((lags - d_true) ** 2).astype(np.float32)
    k, off = winner(agg, 5, agg.min())
    assert k == 2 and lags[k] + off == pytest.approx(d_true, abs=1e-6)
    nan = np.full(5, np.nan, np.float32)                          # NaN costs: the search stays in the range
    assert 0 <= winner(nan, 5, np.float32(np.nan))[0] <= 4
    assert winner(agg, 2, agg[:2].min()) == (1, 0.0)              # the last searched lag: no parabola
    rng = np.random.default_rng(3)
    echo = rng.uniform(-1, 1, (5, 3, 16)).astype(np.float32)
    index = rng.integers(0, 5, (3, 16)).astype(np.int32)
    own, other = echo_at_winner(echo, lags, index)
    for y in range(3):
        for x in range(16):
            k = index[y, x]
            assert own[y, x] == echo[k, y, x]
            assert other[y, x] == (echo[k, y, x + lags[k]] if x + lags[k] < 16 else NO_TWIN)
    with pytest.raises(ValueError, match="lag indices"):
        echo_at_winner(echo, lags, index + 5)


def test_bad_windows_and_lags_are_rejected():
    f = np.zeros((20, 20), np.float32)
    with pytest.raises(ValueError, match="odd"):
        echo_correlation(f, np.array([3]), window=4)
    with pytest.raises(ValueError, match="lags must lie"):
        echo_correlation(f, np.array([3, 20]), window=5)


def test_aperture_weight_sees_only_variation_along_x():
    y, x = np.mgrid[0:60, 0:80].astype(np.float64)
    horizontal = np.sin(y / 1.5)                    # stripes along x: the same at every lag
    vertical = np.sin(x / 1.5)                      # stripes across x: pin the lag
    diagonal = np.sin((x + y) / 2.0)                # half the gradient energy along x
    inner = (slice(10, 50), slice(10, 70))
    assert np.all(aperture_weight(horizontal, 7, 0.2)[inner] < 1e-6)
    assert np.all(aperture_weight(vertical, 7, 0.2)[inner] == 1.0)
    np.testing.assert_allclose(aperture_weight(diagonal, 7, 0.8)[inner], 0.5 / 0.8, atol=0.02)
    t = band_pass(texture(60, 80, seed=4), 0.7)    # isotropic texture: about half along x, so full weight
    assert np.mean(aperture_weight(t, 7, 0.2)[inner] == 1.0) > 0.95


def test_filter_volume_is_a_double_box_mean_under_a_flat_guide_and_stops_at_guide_edges():
    rng = np.random.default_rng(5)
    vol = rng.random((2, 30, 40)).astype(np.float32)
    vol[1, :, :6] = NO_TWIN
    flat = filter_volume(vol, np.zeros((30, 40), np.float32), 2, 0.01)
    box = lambda a: np.mean([np.roll(np.roll(a, i, 0), j, 1) for i in range(-2, 3) for j in range(-2, 3)], 0)  # noqa: E731
    np.testing.assert_allclose(flat[0, 5:-5, 5:-5], box(box(vol[0]))[5:-5, 5:-5], atol=1e-5)  # a = 0, b = box
    assert np.all(flat[1, :, :6] == NO_TWIN)        # missing twins stay missing
    # a cost that is 1 left of a guide edge and 0 right of it keeps its step (a box would blur it over 9 px)
    step = np.zeros((1, 30, 40), np.float32)
    step[0, :, :20] = 1.0
    guide = np.where(np.arange(40) < 20, 0.0, 1.0)[None, :].repeat(30, 0).astype(np.float32)
    out = filter_volume(step, guide, 4, 1e-4)[0]
    assert np.all(out[:, 15:20] > 0.98) and np.all(np.abs(out[:, 20:25]) < 0.02)


@pytest.mark.parametrize("radius, shape", [(4, (48, 64)), (2, (17, 23)), (1, (16, 16)), (7, (8, 12))])
def test_filter_volume_matches_opencv_box_filters_everywhere(radius, shape):
    """The Numba guided filter against He et al.'s formulas with OpenCV's boxFilter (BORDER_REFLECT), borders
    included."""
    import cv2
    rng = np.random.default_rng(radius)
    vol = rng.uniform(-1, 1, (3, *shape)).astype(np.float32)
    vol[2, :, :5] = NO_TWIN
    guide = rng.random(shape).astype(np.float32)
    k = (2 * radius + 1, 2 * radius + 1)
    box = lambda a: cv2.boxFilter(a, -1, k, borderType=cv2.BORDER_REFLECT)  # noqa: E731
    mg = box(guide)
    vg = box(guide * guide) - mg * mg
    got = filter_volume(vol, guide, radius, 0.01)
    for i in range(3):
        p = np.where(vol[i] == NO_TWIN, 0.0, vol[i]).astype(np.float32)
        mp = box(p)
        a = (box(guide * p) - mg * mp) / (vg + 0.01)
        want = box(a) * guide + box(mp - a * mg)
        want[vol[i] == NO_TWIN] = NO_TWIN
        np.testing.assert_allclose(got[i], want, atol=2e-5)
    inp = vol.copy()
    again = filter_volume(inp, guide, radius, 0.01, in_place=True)   # over its input: the same values
    assert again is inp
    np.testing.assert_array_equal(again, got)      # exactly: on failure it says where and by how much
    weight = rng.random(shape).astype(np.float32)                    # weighted as it is written
    weighted = filter_volume(vol, guide, radius, 0.01, weight=weight)
    np.testing.assert_allclose(weighted, np.where(vol == NO_TWIN, NO_TWIN, got * weight), atol=1e-6)
    with pytest.raises(ValueError, match="weight"):
        filter_volume(vol, guide, radius, 0.01, weight=weight[:-1])
    with pytest.raises(ValueError, match="radius"):
        filter_volume(vol, guide, 0, 0.01)
    with pytest.raises(ValueError, match="radius"):
        filter_volume(vol, guide, min(shape), 0.01)
    with pytest.raises(ValueError, match="eps"):
        filter_volume(vol, guide, radius, 0.0)
    with pytest.raises(ValueError, match="guide"):
        filter_volume(vol, guide[:-1], radius, 0.01)


@pytest.mark.parametrize("seed", [7, 8])
def test_one_sided_costs_against_their_definition(seed):
    """Each pixel's cost in either view, straight from the docstring: the fused cost (``fused_cost`` of the
    echo) where the view owns the pixel, zero in the band where its twin may be outside, else the view's own
    echo (at x, or seen from x + d) negated and shifted to a minimum of 0; the padding PAD_COST. Written over
    the fused cost's own volume, the same to the bit (the second pass's one volume of costs)."""
    from psvs.dense.cost import one_sided_cost, padded_lags
    rng = np.random.default_rng(seed)
    lags = np.arange(3, 14)
    n, h, w = len(lags), 6, 40
    echo = rng.uniform(-1, 1, (n, h, w)).astype(np.float32)
    fused = fused_cost(echo, lags)
    keeps = rng.random((2, h, w)) < 0.3
    for right_view, keep in zip((False, True), keeps, strict=True):
        got = one_sided_cost(echo, lags, keep, right_view, np.full((h, w, padded_lags(n)), np.nan, np.float32))
        _check_one_sided(got, echo, lags, fused, keep, right_view)
        over = fused_cost(echo, lags)
        np.testing.assert_array_equal(one_sided_cost(echo, lags, keep, right_view, over), got)
        assert np.array_equal(got[keep], fused[keep])          # the fused cost made again: the same bits


def _check_one_sided(got, echo, lags, fused, keep, right_view):
    n, h, w = echo.shape
    for y in range(h):
        for x in range(w):
            if keep[y, x]:
                want = fused[y, x, :n]
            elif (x >= w - lags[-1]) if right_view else (x < lags[-1]):
                want = np.zeros(n)
            else:
                own = np.array([(echo[k, y, x + d] if x + d < w else NO_TWIN) if right_view else echo[k, y, x]
                                for k, d in enumerate(lags)])
                want = -own - (-own).min()
            np.testing.assert_allclose(got[y, x, :n], want, atol=1e-6)
    assert np.all(got[:, :, n:] == PAD_COST)
