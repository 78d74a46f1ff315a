"""The band search of the coarse-to-fine pyramid: band SGM against the recursion written out per pixel
with each pixel's own lags, band costs against a direct NCC, the number of levels from size and range, and
planted layers on an image of 1280 x 960 px recovered through the pyramid as well as at 640 x 480."""
import numpy as np
import pytest

from psvs.dense import DEFAULT, FAST, dense_disparity
from psvs.dense.band import band_costs, band_winners
from psvs.dense.evaluate import disparity_scores, superimpose
from psvs.dense.pyramid import pyramid_levels, window_stats
from psvs.dense.sgm import PATHS
from tests.dense.planted import layered_pair


def reference_band_sgm(cost, off, p1, p2, paths):
    """Hirschmüller's recursion one pixel at a time, pixel p's lane k being disparity off[p] + k: the
    previous pixel's lane of the same disparity continues free, those one disparity away cost p1, any
    other lane p2 (its minimum). Returns the summed path costs (H, W, B)."""
    h, w, n = cost.shape
    total = np.zeros(cost.shape)
    for dy, dx in paths:
        lr = np.zeros(cost.shape)
        ys = range(h) if dy >= 0 else range(h - 1, -1, -1)
        xs = list(range(w)) if dx >= 0 else list(range(w - 1, -1, -1))
        for y in ys:
            for x in xs:
                py, px = y - dy, x - dx
                if not (0 <= py < h and 0 <= px < w):
                    lr[y, x] = cost[y, x]
                    continue
                prev, m = lr[py, px], lr[py, px].min()
                d_prev = off[py, px] + np.arange(n)
                for k in range(n):
                    d = off[y, x] + k
                    cands = [m + p2] + [prev[j] + (0 if dd == d else p1) for j, dd in enumerate(d_prev)
                                        if abs(dd - d) <= 1]
                    lr[y, x, k] = cost[y, x, k] + min(cands) - m
        total += lr
    return total


@pytest.mark.parametrize("n_paths", [4, 8])
def test_band_sgm_matches_the_recursion_with_each_pixels_own_lags(n_paths):
    rng = np.random.default_rng(n_paths)
    h, w, n = 9, 11, 8
    cost = rng.random((h, w, n)).astype(np.float32)
    off = rng.integers(10, 30, (h, w))
    off[2:6, 3:8] = 17                         # a region of one band, and steps of all sizes around it
    off[4, :] = off[3, :] + rng.integers(-2, 3, w)
    ref = reference_band_sgm(cost, off, 0.3, 2.0, PATHS[:n_paths])
    best = band_winners(np.stack([cost, cost[::-1].copy()]), np.stack([off, off[::-1].copy()]), 0.3, 2.0, n_paths,
                        np.zeros((h, w), np.float32), 1.0)
    k_ref = np.argmin(ref, axis=2)
    assert np.all(np.abs(best[0] - (off + k_ref)) <= 0.5 + 1e-9)
    assert best.shape == (2, h, w)


def test_band_sgm_with_one_band_everywhere_is_plain_sgm():
    from psvs.dense.sgm import Penalties, winners
    rng = np.random.default_rng(3)
    cost = rng.random((30, 40, 16)).astype(np.float32)
    guide = rng.random((30, 40)).astype(np.float32)
    ref, _ = winners(cost, 16, Penalties(0.3, 2.0, 8, guide, 0.1))
    best = band_winners(np.stack([cost, cost]), np.full((2, 30, 40), 7), 0.3, 2.0, 8, guide, 0.1)
    np.testing.assert_allclose(best[0], ref + 7, atol=1e-5)


def test_band_costs_are_the_windows_ncc():
    """Lane k of the left map at x: NCC of the 5x5 window at x with the one at x - (off + k), by numpy;
    the right map's: the window at x + d with the one at x. Costs are the best echo minus the echo."""
    rng = np.random.default_rng(0)
    f = rng.standard_normal((20, 60)).astype(np.float32)
    off = rng.integers(3, 12, (2, 20, 60))
    r, n = 2, 6
    mu, isd = window_stats(f, r)
    ones = np.ones_like(f)
    costs, top = band_costs(f, f, (mu, isd, mu, isd, ones), off, 40, n, r)
    pad = np.pad(f, r, mode="edge")
    win = lambda y, x: pad[y:y + 2 * r + 1, x:x + 2 * r + 1].ravel()  # noqa: E731

    def ncc(a, b):
        return np.mean(a * b) / (a.std() * b.std()) - a.mean() * b.mean() / (a.std() * b.std())
    for y, x in [(5, 30), (10, 20), (0, 45), (19, 14)]:
        for k in range(n):
            d = off[0, y, x] + k
            e = ncc(win(y, x), win(y, x - d))
            assert top[0, y, x] - costs[0, y, x, k] == pytest.approx(e, abs=2e-3)
            d = off[1, y, x] + k
            e = ncc(win(y, x + d), win(y, x))
            assert top[1, y, x] - costs[1, y, x, k] == pytest.approx(e, abs=2e-3)
    assert np.all(costs >= 0)
    assert np.all(costs[0, :, 0, :] == 0)          # x = 0: no twin at any lag, a neutral cost


def test_levels_come_from_the_size_and_the_range():
    assert pyramid_levels(480, 640, 86, 255) == 0        # the default rig: the method as it was
    assert pyramid_levels(480, 640, 0, 64) == 0
    assert pyramid_levels(500, 741, 0, 160) == 0         # Motorcycle over the widest range its tests search
    assert pyramid_levels(509, 663, 84, 255) == 0        # the misaligned rig's rectified grids, 400-1200 mm
    assert pyramid_levels(1130, 1502, 200, 392) == 1     # mv1440 rectified, 550-1100 mm
    assert pyramid_levels(1080, 1440, 181, 519) == 2     # mv1440, 400-1200 mm
    assert pyramid_levels(2160, 2880, 0, 120) == 2       # a large image, a small range: by its size
    assert pyramid_levels(1080, 1440, 0, 20) == 0        # too few lags to halve


@pytest.fixture(scope="module")
def large_pair():
    """Planted layers at 1280 x 960 px: background at 58 px, a 320 x 240 px foreground at 97 px."""
    return layered_pair(h=960, w=1280, d_bg=58, d_fg=97, rect=(300, 540, 400, 720), seed=4)


@pytest.mark.parametrize("params, bad2", [(DEFAULT, 4.0), (FAST, 6.0)])
def test_planted_layers_through_the_pyramid(large_pair, params, bad2):
    """Searched over 3..200 px the image gets a level; both maps within 2 px on as many pixels as the
    640 x 480 pair gives (3.8 % and 5.7 % bad-2, docs/dense.md), confidence where the left-right check holds."""
    left, right, tl, tr = large_pair
    assert pyramid_levels(960, 1280, 0, 200) >= 1
    res = dense_disparity(superimpose(left, right), 0, 200, params=params)
    assert res.disparity_left.shape == left.shape
    for d, truth in ((res.disparity_left, tl), (res.disparity_right, tr)):
        assert disparity_scores(d, truth)["bad2_pct"] < bad2
    c = res.confidence_left
    assert 0 <= c.min() and c.max() <= 1 and np.mean(c > 0) > 0.5
    assert np.mean(np.abs(res.disparity_left - tl)[c > 0] <= 1) > 0.95


def test_memory_of_a_pyramid_is_the_coarse_levels_and_the_bands():
    """1502 x 1130 over 181..519 px: two levels; the estimate is the coarse level's (halved twice, a quarter
    of the range, the default mode unpruned: DEFAULT.top) plus 16 B per pixel and band lag plus 400 B per
    pixel, about an eighth of the one-level search's (its cells at 12 B against 496 B a pixel and 338 lags)."""
    from dataclasses import replace

    from psvs.dense.disparity import BAND_BYTES, PIXEL_BYTES, dense_memory_bytes
    h, w = 1130, 1502
    need = dense_memory_bytes(h, w, 181, 519)
    assert DEFAULT.top == replace(DEFAULT, prune=False, top=None)
    coarse = dense_memory_bytes(h // 4, w // 4, 181 / 4, 519 / 4, replace(DEFAULT, prune=False, pyramid=False,
                                                                            top=None))
    assert need == coarse + BAND_BYTES * DEFAULT.band_lags * h * w + PIXEL_BYTES * h * w
    assert need < 0.15 * dense_memory_bytes(h, w, 181, 519, replace(DEFAULT, pyramid=False))
    fast = dense_memory_bytes(h, w, 181, 519, FAST)
    assert fast < need


def test_band_parameters_are_checked():
    from dataclasses import replace
    with pytest.raises(ValueError, match="band_lags must be >= 4"):
        replace(DEFAULT, band_lags=2)
    with pytest.raises(ValueError, match="refine_window must be an odd number"):
        replace(DEFAULT, refine_window=4)
    with pytest.raises(ValueError, match="refine_median_px must be an odd number"):
        replace(DEFAULT, refine_median_px=0)


def test_a_kept_workspace_gives_the_same_maps_through_the_pyramid(large_pair):
    """The band volumes are kept in the Workspace with the coarse level's: a second frame with it gives the
    same maps as a call without one, and a first frame of another range too (the volumes regrow)."""
    from psvs.dense import Workspace
    left, right, _, _ = large_pair
    c = superimpose(left, right)
    ws = Workspace()
    for d_max in (200, 200, 150):
        ref = dense_disparity(c, 0, d_max, params=FAST)
        res = dense_disparity(c, 0, d_max, params=FAST, workspace=ws)
        np.testing.assert_array_equal(res.disparity_left, ref.disparity_left)
        np.testing.assert_array_equal(res.confidence_right, ref.confidence_right)


@pytest.mark.parametrize("n", [6, 5, 9])
def test_local_winners_sum_each_disparity_over_the_window(n):
    """band_local_winners against a direct sum: each pixel's lane k is disparity o + k; a neighbour adds its
    cost at that disparity when its band holds it, else its worst cost; the winner is the lowest sum (with a
    parabola's offset within half a lane). Bands of psvs.dense.band.LANES lanes (its own compiled copy) and
    of others."""
    from psvs.dense.band import band_local_winners
    rng = np.random.default_rng(3)
    h, w = 9, 11
    costs = rng.random((2, h, w, n)).astype(np.float32)
    offs = rng.integers(20, 23, (2, h, w))
    best = band_local_winners(costs, offs, 1)
    for i in range(2):
        for y in range(h):
            for x in range(w):
                acc = np.zeros(n)
                for yy in range(max(0, y - 1), min(h, y + 2)):
                    for xx in range(max(0, x - 1), min(w, x + 2)):
                        c = costs[i, yy, xx]
                        for k in range(n):
                            j = k + offs[i, y, x] - offs[i, yy, xx]
                            acc[k] += c[j] if 0 <= j < n else c.max()
                k = int(np.argmin(acc))
                assert abs(best[i, y, x] - (offs[i, y, x] + k)) <= 0.5
    with pytest.raises(ValueError, match="radius must be >= 0"):
        band_local_winners(costs, offs, -1)


def test_the_copies_for_the_default_lanes_give_the_general_numbers():
    """The kernels compiled for psvs.dense.band.LANES lanes (a constant count) and their general copies give the
    same numbers bit for bit on bands of that many lanes: the aggregation (4 and 8 paths) and the local winners."""
    from psvs.dense import band
    rng = np.random.default_rng(8)
    h, w, n = 40, 70, band.LANES
    costs = rng.random((2, h, w, n)).astype(np.float32)
    offs = (rng.integers(30, 33, (2, h, w)) + (rng.random((2, h, w)) < 0.2)).astype(np.int64)
    guide = (rng.random((h, w)) * 60).astype(np.float32)
    for diagonals in (False, True):
        got, want = np.empty((2, h, w)), np.empty((2, h, w))
        args = (costs, offs, diagonals, np.float32(0.1), np.float32(0.6), guide, np.float32(12.0))
        band._band_winners_lanes(*args, np.empty_like(costs), got)
        band._band_winners(*args, np.empty_like(costs), want)
        np.testing.assert_array_equal(got, want)
    got, want = np.empty((2, h, w)), np.empty((2, h, w))
    band._local_winners_lanes(costs, offs, 2, got)
    band._local_winners(costs, offs, 2, want)
    np.testing.assert_array_equal(got, want)
