import numpy as np
import pytest

from psvs.dense.sgm import PATHS, Penalties, aggregate, winners


def reference_sgm(cost, p1, p2, paths, guide=None, tau=1.0):
    """Plain Python SGM straight from Hirschmüller's recursion, one pixel at a time; with a guide, the jump
    penalty is max(p1, p2 / (1 + |ΔI| / tau))."""
    h, w, n = cost.shape
    total = np.zeros_like(cost, dtype=np.float64)
    for dy, dx in paths:
        lr = np.zeros_like(cost, dtype=np.float64)
        ys = range(h) if dy >= 0 else range(h - 1, -1, -1)
        xs = list(range(w)) if dx >= 0 else list(range(w - 1, -1, -1))
        for y in ys:
            for x in xs:
                py, px = y - dy, x - dx
                if not (0 <= py < h and 0 <= px < w):
                    lr[y, x] = cost[y, x]
                    continue
                prev = lr[py, px]
                m = prev.min()
                jump = p2 if guide is None else max(p1, p2 / (1 + abs(guide[y, x] - guide[py, px]) / tau))
                for d in range(n):
                    cands = [prev[d], m + jump]
                    if d > 0:
                        cands.append(prev[d - 1] + p1)
                    if d < n - 1:
                        cands.append(prev[d + 1] + p1)
                    lr[y, x, d] = cost[y, x, d] + min(cands) - m
        total += lr
    return total


@pytest.mark.parametrize("n_paths", [4, 8])
def test_aggregate_matches_reference_recursion(n_paths):
    rng = np.random.default_rng(1)
    cost = rng.random((7, 9, 5)).astype(np.float32)
    got = aggregate(cost, Penalties(0.1, 0.4, n_paths=n_paths))
    want = reference_sgm(cost.astype(np.float64), 0.1, 0.4, PATHS[:n_paths])
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)
    # one thread, and caller's buffers (written over, the result is the first)
    out, work = np.full_like(cost, np.nan), np.full_like(cost, np.nan)
    again = aggregate(cost, Penalties(0.1, 0.4, n_paths=n_paths), threads=1, out=out, work=work)
    assert again is out and np.array_equal(again, got)
    # negative costs (the kernel needs >= 0): shifted in and out, still the recursion's result
    below = aggregate(cost - 0.6, Penalties(0.1, 0.4, n_paths=n_paths))
    np.testing.assert_allclose(below, want - 0.6 * n_paths, rtol=1e-5, atol=1e-5)
    with pytest.raises(ValueError, match="SGM buffers"):
        aggregate(cost, Penalties(0.1, 0.4), out=np.empty((7, 9, 4), np.float32))
    with pytest.raises(ValueError, match="overlap"):
        aggregate(cost, Penalties(0.1, 0.4), out=cost)


def reference_winner(agg, n_valid):
    """Index of the lowest of agg[..., :n_valid] plus a parabola's offset (within ±0.5, none at the ends)."""
    k = np.argmin(agg[..., :n_valid], axis=-1)
    kc = np.clip(k, 1, n_valid - 2)
    c0, c1, c2 = (np.take_along_axis(agg, (kc + j)[..., None], -1)[..., 0] for j in (-1, 0, 1))
    den = c0 - 2 * c1 + c2
    off = np.where(den > 1e-9, np.clip(0.5 * (c0 - c2) / np.where(den > 1e-9, den, 1), -0.5, 0.5), 0.0)
    return k + np.where((k > 0) & (k < n_valid - 1), off, 0.0), k


@pytest.mark.parametrize("n_paths", [4, 8])
@pytest.mark.parametrize("h", [1, 2, 3, 8, 9])
def test_winners_are_the_aggregated_costs_lowest_lags(n_paths, h):
    """winners finds the lowest of the recursion's sums over the first n_valid lags, with the parabola's
    offset: one volume (the two passes meeting in the middle; odd and even heights, down to one row,
    where one pass has no rows in its first half) and two at once (one per thread); the lags past
    n_valid (padding) never win; negative costs are refused, also when the caller vouched for them."""
    rng = np.random.default_rng(5 + n_paths + h)
    costs = rng.random((2, h, 11, 8)).astype(np.float32)
    costs[:, :, :, 6:] = 0.0                     # padding that would win were it searched
    guide = rng.random((h, 11)).astype(np.float32)
    want = [reference_winner(reference_sgm(c.astype(np.float64), 0.1, 0.4, PATHS[:n_paths], guide.astype(np.float64),
                                           0.3), 6) for c in costs]
    args = dict(n_paths=n_paths, guide=guide, tau=0.3)
    best, index = winners(costs, 6, Penalties(0.1, 0.4, **args), sums=np.full_like(costs, np.nan))
    one = [winners(c, 6, Penalties(0.1, 0.4, **args), sums=np.full_like(c, np.nan)) for c in costs]
    for i in range(2):
        for b, k in ((best[i], index[i]), one[i]):
            np.testing.assert_allclose(b, want[i][0], atol=1e-4)
            assert np.array_equal(k, want[i][1]) and np.all(np.abs(b - k) <= 0.5)
    with pytest.raises(ValueError, match="one cost volume"):
        winners(costs[:, :, :, :, None], 6, Penalties(0.1, 0.4))
    with pytest.raises(ValueError, match="n_valid"):
        winners(costs, 9, Penalties(0.1, 0.4))
    with pytest.raises(ValueError, match="costs >= 0"):
        winners(costs - 0.5, 6, Penalties(0.1, 0.4))
    for bad in (costs - 0.5, costs[0] - 0.5):                       # caught by the kernel's integer minimum
        with pytest.raises(ValueError, match="costs >= 0"):
            winners(bad, 6, Penalties(0.1, 0.4), min_cost=0.0)
    with pytest.raises(ValueError, match="overlap"):
        winners(costs, 6, Penalties(0.1, 0.4), sums=costs)
    with pytest.raises(ValueError, match="penalties"):
        winners(costs, 6, Penalties(0.5, 0.4))


def test_guided_penalty_matches_reference_recursion():
    rng = np.random.default_rng(2)
    cost = rng.random((6, 8, 5)).astype(np.float32)
    guide = (rng.random((6, 8)) * 3).astype(np.float32)
    got = aggregate(cost, Penalties(0.1, 0.9, guide=guide, tau=0.5))
    want = reference_sgm(cost.astype(np.float64), 0.1, 0.9, PATHS, guide.astype(np.float64), 0.5)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)
    flat = aggregate(cost, Penalties(0.1, 0.9, guide=np.ones((6, 8), np.float32), tau=0.5))
    np.testing.assert_allclose(flat, aggregate(cost, Penalties(0.1, 0.9)), rtol=1e-6)   # no edge: the plain penalty


def test_aggregation_fills_an_uninformative_gap():
    # a clear minimum at d=3 everywhere except a flat-cost hole: SGM carries d=3 into the hole
    cost = np.ones((20, 20, 8), np.float32)
    cost[:, :, 3] = 0.0
    cost[8:12, 8:12, :] = 0.5
    agg = aggregate(cost, Penalties(0.1, 1.0))
    assert np.all(np.argmin(agg, axis=2) == 3)


def test_penalties_are_checked():
    with pytest.raises(ValueError, match="p1 <= p2"):
        aggregate(np.zeros((3, 3, 2), np.float32), Penalties(1.0, 0.5))
    with pytest.raises(ValueError, match="n_paths"):
        aggregate(np.zeros((3, 3, 2), np.float32), Penalties(0.1, 0.5, n_paths=6))
    with pytest.raises(ValueError, match="tau"):
        aggregate(np.zeros((3, 3, 2), np.float32), Penalties(0.1, 0.5, guide=np.zeros((3, 3)), tau=0.0))
    with pytest.raises(ValueError, match="guide"):
        aggregate(np.zeros((3, 3, 2), np.float32), Penalties(0.1, 0.5, guide=np.zeros((3, 4))))
