"""The band search of the coarse-to-fine pyramid (psvs.dense.pyramid): each pixel searches only B
consecutive disparities o(p) .. o(p) + B − 1 around what the coarser level found there, as tSGM does
(Rothermel et al. 2012), so a level costs pixels × B instead of pixels × the whole range.

Each view's map is refined from its own evidence. The echo of a left-view point at x with disparity d is
the normalised cross-correlation of C's band-passed window at x with the window at x − d (on a build, the
right view's rectified grid at x − d); a right-view point at x is seen from its left-view end, x + d.
Both are computed directly, window by window, for the pixel's B lags only (no volume over the range), and
weighted by the aperture of the left-view end's patch (psvs.dense.cost.aperture_weight).

Semi-global aggregation (Hirschmüller 2008) runs over the bands: along a path from q to p, lane k of p
(disparity o(p) + k) continues lane k + o(p) − o(q) of q, with the usual P1 for a one-step change and P2
(lowered across the guide's edges) for a jump; a lane outside q's band continues nothing but the jump.
Two passes (down: from the left, above and the two upper diagonals; up: the opposite ones) on each map,
the two maps on two threads; the up pass adds the down pass's sums and keeps each pixel's winner.
"""
from __future__ import annotations

import cv2
import numba as nb
import numpy as np

from psvs.dense.fastmath import SAFE_MATH
from psvs.dense.sgm import _penalty, winner

_BIG = np.float32(1e30)    # a lane outside a band: never a path's minimum (finite: fastmath)


#: The lanes of a band the default parameters give (``DenseParams.band_lags``): the kernels have a copy compiled
#: for that count, whose lane loops the compiler unrolls (the band aggregation 1.3 times faster, the local
#: winners 1.5 times, the same numbers); other counts run the general copy.
LANES = 6


@nb.njit(cache=True, fastmath=SAFE_MATH, inline="always")
def _costs_row(fp, grp, stats, offs, r, d_hi, costs, tops, task, nb_):  # noqa: PLR0913  # pragma: no cover - compiled
    """Row ``task`` of :func:`_band_costs` (the left view's row ``task``, or the right view's row ``task`` − H);
    ``nb_`` the lanes (a constant in the copy for :data:`LANES`). Arrays are read element by element, never
    through a row view: a view costs an atomic reference count, shared by the threads (docs/dense-speed.md)."""
    h, w = costs.shape[1], costs.shape[2]
    wp = fp.shape[1]
    pad = (wp - w) // 2
    inv = np.float32(1.0 / ((2 * r + 1) * (2 * r + 1)))
    right_view = task >= h
    v = 1 if right_view else 0
    y = task - h if right_view else task
    acc = np.empty(nb_, np.float32)
    e = np.empty(nb_, np.float32)
    for x in range(w):
        o = offs[v, y, x]
        n_ok = min(nb_, d_hi - o + 1, (w - x - o) if right_view else (x - o + 1))
        if n_ok <= 0:
            for k in range(nb_):
                costs[v, y, x, k] = 0.0
            tops[v, y, x] = 0.0
            continue
        for k in range(nb_):
            acc[k] = 0.0
        for j in range(2 * r + 1):
            for i in range(-r, r + 1):
                if right_view:        # Σ f(x + d + i) g(x + i): f runs forward with the lag
                    gv = grp[y + j, wp - 1 - (x + i + pad)]
                    c0 = x + i + o + pad
                    for k in range(nb_):
                        acc[k] += fp[y + j, c0 + k] * gv
                else:                 # Σ f(x + i) g(x − d + i): g reversed runs forward with the lag
                    fv = fp[y + j, x + i + pad]
                    c0 = wp - 1 - (x + i - o + pad)
                    for k in range(nb_):
                        acc[k] += fv * grp[y + j, c0 + k]
        if right_view:
            c0, cg = x + o + pad, wp - 1 - (x + pad)
            mg, sg = stats[3, y, cg], stats[4, y, cg]
            for k in range(nb_):
                e[k] = (acc[k] * inv - stats[0, y, c0 + k] * mg) * (stats[1, y, c0 + k] * sg) * stats[2, y, c0 + k]
        else:
            mf, sf, a = stats[0, y, x + pad], stats[1, y, x + pad], stats[2, y, x + pad]
            c0 = wp - 1 - (x - o + pad)
            for k in range(nb_):
                e[k] = (acc[k] * inv - mf * stats[3, y, c0 + k]) * (sf * stats[4, y, c0 + k]) * a
        best = e[0]
        for k in range(1, n_ok):
            best = max(best, e[k])
        worst = np.float32(0.0)
        for k in range(n_ok):
            c = best - e[k]
            costs[v, y, x, k] = c
            worst = max(worst, c)
        for k in range(n_ok, nb_):
            costs[v, y, x, k] = worst
        tops[v, y, x] = best


@nb.njit(cache=True, fastmath=SAFE_MATH)
def _costs_row_any(fp, grp, stats, offs, r, d_hi, costs, tops, task):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_costs_row` of any lane count."""
    _costs_row(fp, grp, stats, offs, r, d_hi, costs, tops, task, costs.shape[3])


@nb.njit(cache=True, fastmath=SAFE_MATH)
def _costs_row_lanes(fp, grp, stats, offs, r, d_hi, costs, tops, task):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_costs_row` of :data:`LANES` lanes."""
    _costs_row(fp, grp, stats, offs, r, d_hi, costs, tops, task, LANES)


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _band_costs(fp, grp, stats, offs, r, d_hi, costs, tops):  # noqa: PLR0913  # pragma: no cover - compiled
    """The band costs (H, W, B) of both views' maps into ``costs`` (2, H, W, B) (>= 0, a pixel's best lane
    0; [0] the left view's, [1] the right view's) and each pixel's best echo into ``tops`` (2, H, W) (so
    echo = top − cost on a lane with a twin), rows of both views in parallel.

    ``fp`` (H + 2r, W + 2P) the left features padded by replication (P = r + B + 1 columns, r rows);
    ``grp`` the right features padded the same way and with its columns reversed (so a window at x − d
    for the lags of a band runs forward); ``stats`` (5, H, W + 2P) rows of: the left features' window mean,
    inverse deviation, the aperture weight (padded as ``fp``), the right features' mean and inverse deviation
    (padded and reversed as ``grp``); ``offs`` (2, H, W) int64 the bands' first lags; lanes above ``d_hi`` or
    without a twin in the image take the pixel's worst cost (never favoured), a pixel without any
    an all-zero (neutral) cost."""
    for task in nb.prange(2 * costs.shape[1]):
        _costs_row_any(fp, grp, stats, offs, r, d_hi, costs, tops, np.int64(task))


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _band_costs_lanes(fp, grp, stats, offs, r, d_hi, costs, tops):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_band_costs` of :data:`LANES` lanes."""
    for task in nb.prange(2 * costs.shape[1]):
        _costs_row_lanes(fp, grp, stats, offs, r, d_hi, costs, tops, np.int64(task))


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH, inline="always")
def _band_pass(cost, off, down, diagonals, p1, p2, guide, tau, sums, best, nb_):  # noqa: PLR0913  # pragma: no cover - compiled
    """One pass of the band aggregation (module docstring) over all rows: ``down`` writes its sum of paths
    into ``sums`` (H, W, B); the up pass adds ``sums`` and writes each pixel's winner, as the disparity
    o + lane + sub-pixel offset, into ``best`` (H, W) float64. ``nb_``: B (a constant in a copy for
    :data:`LANES`). Arrays are read element by element, not through row views (:func:`_costs_row`)."""
    h, w = cost.shape[0], cost.shape[1]
    pad = nb_ + 2                                    # lanes of padding each side of a band in the states
    n_k = 4 if diagonals else 2                      # 0 the row's path, 1 from above, 2 from x − s, 3 from x + s
    s = 1 if down else -1
    state = np.full((2, n_k, w + 2, nb_ + 2 * pad), _BIG, np.float32)
    mins = np.zeros((2, n_k, w + 2), np.float32)
    state[:, :, 0, :] = 0.0                          # outside the image: a zero source, minimum zero (L = c)
    state[:, :, w + 1, :] = 0.0
    offs = np.zeros(w + 2, np.int64)                 # the bands' first lags, columns shifted by one
    prev_offs = np.zeros(w + 2, np.int64)
    pen = np.empty((n_k, w), np.float32)
    row_sum = np.empty(nb_, np.float32)
    lim = nb_ + 1
    for iy in range(h):
        pi, ci = iy % 2, (iy + 1) % 2                # the previous row's state, this row's
        y = iy if down else h - 1 - iy
        yp = min(max(y - s, 0), h - 1)
        for x in range(w):
            offs[x + 1] = off[y, x]
            prev_offs[x + 1] = off[yp, x] if iy > 0 else off[y, x]
        for x in range(w):
            g = guide[y, x]
            pen[0, x] = _penalty(g, guide[y, min(max(x - s, 0), w - 1)], p1, p2, tau)
            pen[1, x] = _penalty(g, guide[yp, x], p1, p2, tau)
            if diagonals:
                pen[2, x] = _penalty(g, guide[yp, min(max(x - s, 0), w - 1)], p1, p2, tau)
                pen[3, x] = _penalty(g, guide[yp, min(max(x + s, 0), w - 1)], p1, p2, tau)
        for ix in range(w):                          # the row's path, in its own direction
            x = ix if down else w - 1 - ix
            xb, xq = x + 1, x + 1 - s
            dl = 0 if (xq == 0 or xq == w + 1) else min(max(offs[xb] - offs[xq], -lim), lim)
            _step(cost, y, x, state, ci, 0, xq, mins[ci, 0, xq], pen[0, x], p1, pad + dl, state, ci, xb, mins, nb_)
        for x in range(w):                           # the paths from the previous row
            xb = x + 1
            for kk in range(1, n_k):
                xq = xb if kk == 1 else (xb - s if kk == 2 else xb + s)
                if iy == 0:                          # the row before the first: a zero source, L = c
                    lo = np.float32(3e38)
                    for k in range(nb_):
                        state[ci, kk, xb, pad + k] = cost[y, x, k]
                        lo = min(lo, cost[y, x, k])
                    mins[ci, kk, xb] = lo
                    continue
                dl = 0 if (xq == 0 or xq == w + 1) else min(max(offs[xb] - prev_offs[xq], -lim), lim)
                _step(cost, y, x, state, pi, kk, xq, mins[pi, kk, xq], pen[kk, x], p1, pad + dl, state, ci, xb, mins,
                      nb_)
            for k in range(nb_):
                row_sum[k] = state[ci, 0, xb, pad + k]
            for kk in range(1, n_k):
                for k in range(nb_):
                    row_sum[k] += state[ci, kk, xb, pad + k]
            if down:
                for k in range(nb_):
                    sums[y, x, k] = row_sum[k]
            else:
                lowest = np.float32(3e38)
                for k in range(nb_):
                    row_sum[k] += sums[y, x, k]
                    lowest = min(lowest, row_sum[k])
                k, frac = winner(row_sum, nb_, lowest)
                best[y, x] = offs[xb] + k + frac


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH, inline="always")
def _step(cost, y, x, src, si, kk, xq, m, pen, p1, at, dst, ci, xb, mins, nb_):  # noqa: PLR0913  # pragma: no cover - compiled
    """One path's step into pixel (y, x) (column ``xb`` of the states): L(k) = c(k) + min(L_q(k'),
    L_q(k' ± 1) + p1, m + pen) − m with k' = k + shift, L_q path ``kk``'s state at column ``xq`` of ``src``'s
    row ``si`` (``at`` = the padding plus the shift), ``m`` q's minimum; ``nb_`` the lanes of c. Writes path
    ``kk``'s state at column ``xb`` of ``dst``'s row ``ci``, its minimum into ``mins``. (``src`` and ``dst``
    are the same states, passed twice: read and written through two names, the pass ran 15 % faster.)"""
    j = m + pen
    lo = np.float32(3e38)
    base = (dst.shape[3] - nb_) // 2
    for k in range(nb_):
        v = cost[y, x, k] + min(min(src[si, kk, xq, at - 1 + k], src[si, kk, xq, at + 1 + k]) + p1,
                                min(src[si, kk, xq, at + k], j)) - m
        dst[ci, kk, xb, base + k] = v
        lo = min(lo, v)
    mins[ci, kk, xb] = lo


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH)
def _band_map(cost, off, diagonals, p1, p2, guide, tau, sums, best):  # noqa: PLR0913  # pragma: no cover - compiled
    """One map's aggregation: the down pass into ``sums``, the up pass picking into ``best``. The passes are
    inlined here, not in the parallel kernels: Numba's parallel passes over their bodies took most of the
    compile time (20 s for the copy of :data:`LANES` lanes). (An inlined function compiles with its caller's
    fast-math flags: without them here, the passes' minima did not vectorise.)"""
    _band_pass(cost, off, True, diagonals, p1, p2, guide, tau, sums, best, cost.shape[2])
    _band_pass(cost, off, False, diagonals, p1, p2, guide, tau, sums, best, cost.shape[2])


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH)
def _band_map_lanes(cost, off, diagonals, p1, p2, guide, tau, sums, best):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_band_map` of :data:`LANES` lanes."""
    _band_pass(cost, off, True, diagonals, p1, p2, guide, tau, sums, best, LANES)
    _band_pass(cost, off, False, diagonals, p1, p2, guide, tau, sums, best, LANES)


@nb.njit(cache=True, parallel=True)
def _band_winners(costs, offs, diagonals, p1, p2, guide, tau, sums, best):  # noqa: PLR0913  # pragma: no cover - compiled
    """Both maps' aggregation, one per thread (:func:`_band_map`)."""
    for i in nb.prange(costs.shape[0]):
        _band_map(costs[i], offs[i], diagonals, p1, p2, guide, tau, sums[i], best[i])


@nb.njit(cache=True, parallel=True)
def _band_winners_lanes(costs, offs, diagonals, p1, p2, guide, tau, sums, best):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_band_winners` of :data:`LANES` lanes."""
    for i in nb.prange(costs.shape[0]):
        _band_map_lanes(costs[i], offs[i], diagonals, p1, p2, guide, tau, sums[i], best[i])


def band_winners(costs: np.ndarray, offsets: np.ndarray, p1: float, p2: float, n_paths: int, guide: np.ndarray,
                 tau: float, sums: np.ndarray | None = None) -> np.ndarray:
    """Each pixel's winning disparity (px, float64 (2, H, W): lag o + lane + a parabola's sub-pixel offset)
    of the SGM aggregation over the bands of two maps: ``costs`` (2, H, W, B) >= 0 (lane k of pixel p is
    disparity offsets[i, p] + k), ``offsets`` (2, H, W) int, penalties ``p1`` <= ``p2`` (the jump's lowered
    to max(p1, p2 / (1 + |Δguide| / tau)) across ``guide`` (H, W)'s edges), ``n_paths`` 4 or 8. ``sums``:
    work space of the costs' shape."""
    costs = np.ascontiguousarray(costs, dtype=np.float32)
    if costs.ndim != 4 or costs.shape[0] != 2:
        raise ValueError(f"band costs must have shape (2, H, W, B), got {costs.shape}")
    offsets = np.ascontiguousarray(offsets, dtype=np.int64)
    if offsets.shape != costs.shape[:3]:
        raise ValueError(f"band offsets {offsets.shape} must match the costs' {costs.shape[:3]}")
    if n_paths not in (4, 8):
        raise ValueError(f"n_paths must be 4 or 8, got {n_paths}")
    if not 0 <= p1 <= p2:
        raise ValueError(f"SGM penalties need 0 <= p1 <= p2, got p1={p1}, p2={p2}")
    guide = np.ascontiguousarray(guide, dtype=np.float32)
    if guide.shape != costs.shape[1:3]:
        raise ValueError(f"guide {guide.shape} must match the cost's image size {costs.shape[1:3]}")
    if sums is None:
        sums = np.empty_like(costs)
    best = np.empty(costs.shape[:3], np.float64)
    kernel = _band_winners_lanes if costs.shape[3] == LANES else _band_winners
    kernel(costs, offsets, n_paths == 8, np.float32(p1), np.float32(p2), guide, np.float32(tau), sums, best)
    return best


def band_costs(features_left: np.ndarray, features_right: np.ndarray, stats: tuple, offsets: np.ndarray,
               d_hi: int, n_lanes: int, radius: int, out: np.ndarray | None = None):
    """The band costs of both maps (psvs.dense.band module docstring): float32 (2, H, W, B) >= 0, [0] the
    left view's (echo at x, twin at x − d), [1] the right view's (echo seen from x + d), lane k the lag
    offsets[i] + k (lags above ``d_hi`` and those without a twin in the image get the pixel's worst cost),
    and each pixel's best echo (2, H, W), so the echo of a lane is best − cost. ``features_*`` (H, W)
    band-passed images (the same one on the paper's geometry); ``stats``: (mean, inverse deviation) of
    each over the (2 radius + 1)² window and the left one's aperture weight, each (H, W)."""
    f = np.asarray(features_left, dtype=np.float32)
    h, w = f.shape
    pad = radius + n_lanes + 1
    edge = lambda a, rows, dst=None: cv2.copyMakeBorder(np.asarray(a, np.float32), rows, rows, pad, pad,  # noqa: E731
                                                        cv2.BORDER_REPLICATE, dst=dst)
    fp = edge(f, radius)
    grp = cv2.flip(edge(features_right, radius), 1)        # columns reversed
    mu_f, isd_f, mu_g, isd_g, aperture = stats
    st = np.empty((5, h, w + 2 * pad), np.float32)
    for k, (a, reverse) in enumerate(((mu_f, False), (isd_f, False), (aperture, False), (mu_g, True), (isd_g, True))):
        if reverse:       # written into their rows of st: one copy less of each (1.5 MP: 5 x 7 MB)
            cv2.flip(edge(a, 0), 1, dst=st[k])
        else:
            edge(a, 0, st[k])
    costs = np.empty((2, h, w, n_lanes), np.float32) if out is None else out
    top = np.empty((2, h, w), np.float32)
    offsets = np.ascontiguousarray(offsets, dtype=np.int64)
    kernel = _band_costs_lanes if n_lanes == LANES else _band_costs
    kernel(fp, grp, st, offsets, radius, int(d_hi), costs, top)
    return costs, top


@nb.njit(cache=True, fastmath=SAFE_MATH, inline="always")
def _local_row(costs, offs, r, best, task, nb_):  # noqa: PLR0913  # pragma: no cover - compiled
    """Row ``task`` (map task // H, row task % H) of :func:`_local_winners`; ``nb_`` the lanes (a constant in
    the copy for :data:`LANES`)."""
    h, w = costs.shape[1], costs.shape[2]
    i = task // h
    y = task - i * h
    acc = np.empty(nb_, np.float32)
    y0, y1 = max(0, y - r), min(h, y + r + 1)
    for x in range(w):
        o = offs[i, y, x]
        for k in range(nb_):
            acc[k] = 0.0
        for yy in range(y0, y1):
            for xx in range(max(0, x - r), min(w, x + r + 1)):
                shift = o - offs[i, yy, xx]      # scalars, not row views: a view costs an atomic refcount
                if shift == 0:
                    for k in range(nb_):
                        acc[k] += costs[i, yy, xx, k]
                    continue
                worst = costs[i, yy, xx, 0]
                for k in range(1, nb_):
                    worst = max(worst, costs[i, yy, xx, k])
                for k in range(nb_):
                    j = k + shift
                    acc[k] += costs[i, yy, xx, j] if 0 <= j < nb_ else worst
        lowest = acc[0]
        for k in range(1, nb_):
            lowest = min(lowest, acc[k])
        k, frac = winner(acc, nb_, lowest)
        best[i, y, x] = o + k + frac


@nb.njit(cache=True, fastmath=SAFE_MATH)
def _local_row_any(costs, offs, r, best, task):  # pragma: no cover - compiled
    """:func:`_local_row` of any lane count (inlined here, not in the parallel kernel: compile time)."""
    _local_row(costs, offs, r, best, task, costs.shape[3])


@nb.njit(cache=True, fastmath=SAFE_MATH)
def _local_row_lanes(costs, offs, r, best, task):  # pragma: no cover - compiled
    """:func:`_local_row` of :data:`LANES` lanes."""
    _local_row(costs, offs, r, best, task, LANES)


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _local_winners(costs, offs, r, best):  # pragma: no cover - compiled
    """Each pixel's winner over its band of the costs summed, disparity by disparity, over its
    (2r + 1)² neighbours (a neighbour's lane for disparity o(p) + k is k + o(p) − o(q); a disparity outside
    its band adds that neighbour's worst cost), as o + lane + a parabola's sub-pixel offset; rows of both
    maps in parallel. Neighbours on the pixel's own band (most of them: the bands follow a smooth coarser
    map) add lane to lane, in vectors."""
    for task in nb.prange(costs.shape[0] * costs.shape[1]):
        _local_row_any(costs, offs, r, best, task)


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _local_winners_lanes(costs, offs, r, best):  # pragma: no cover - compiled
    """:func:`_local_winners` of :data:`LANES` lanes."""
    for task in nb.prange(costs.shape[0] * costs.shape[1]):
        _local_row_lanes(costs, offs, r, best, task)


def band_local_winners(costs: np.ndarray, offsets: np.ndarray, radius: int) -> np.ndarray:
    """Each pixel's winning disparity (px, float64 (2, H, W)) of two maps' band costs (2, H, W, B) >= 0 (lane
    k of pixel p is disparity offsets[i, p] + k) summed, disparity by disparity, over the (2 radius + 1)²
    window: the finest level's answer where the coarser levels' aggregation already made the map smooth
    (psvs.dense.pyramid; a local sum costs a fifth of a semi-global one there, and is as accurate)."""
    costs = np.ascontiguousarray(costs, dtype=np.float32)
    offsets = np.ascontiguousarray(offsets, dtype=np.int64)
    if costs.ndim != 4 or offsets.shape != costs.shape[:3]:
        raise ValueError(f"band costs (2, H, W, B) and offsets (2, H, W) must match, got {costs.shape}, "
                         f"{offsets.shape}")
    if radius < 0:
        raise ValueError(f"radius must be >= 0, got {radius}")
    best = np.empty(costs.shape[:3], np.float64)
    (_local_winners_lanes if costs.shape[3] == LANES else _local_winners)(costs, offsets, int(radius), best)
    return best
