"""Semi-global aggregation (Hirschmüller 2008) of a matching-cost volume, in Numba.

The recursion along each path r is  L_r(p, d) = c(p, d) + min(L_r(p−r, d), L_r(p−r, d±1) + P1,
min_k L_r(p−r, k) + P2) − min_k L_r(p−r, k); the aggregated cost is the sum over the paths. With a guide
image I, the jump penalty follows Hirschmüller's intensity-adaptive form, P2 / (1 + |I(p) − I(p−r)| / τ)
(never below P1), so depth edges settle on image edges instead of spreading into the weaker-textured side.

The paths run in two passes, as OpenCV's StereoSGBM does: a downward pass (rows top to bottom, each row
left to right) carries the paths that come from the left, the upper left, above and the upper right; an
upward pass the four opposite ones. Each pass reads the cost volume once and writes its sum of paths
once, keeping only the previous row of each path (W × D per path), so the work is bound by arithmetic
rather than memory traffic, and the inner loop over disparities has no branch (rows padded with a large
cost at both ends), so it vectorises. The two passes run on two threads.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba as nb
import numpy as np

#: (dy, dx) of the 8 paths; the first 4 are the horizontal and vertical ones used by the fast mode.
PATHS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))
_BIG = np.float32(1e30)   # the padding of a path's row: never the minimum (finite: the kernels use fastmath)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _step(c, src, m, jump, p1, dst, acc):  # pragma: no cover - compiled
    """One path step: dst[1 + d] = c[d] + min(src[1+d], src[d] + p1, src[2+d] + p1, jump) − m, added to
    acc[d]; returns its minimum. (Three loops: the sum or the minimum taken in the first keeps it from
    vectorising.)"""
    n = c.shape[0]
    for d in range(n):
        near = min(src[d], src[d + 2]) + p1
        dst[d + 1] = c[d] + min(near, min(src[d + 1], jump)) - m
    for d in range(n):
        acc[d] += dst[d + 1]
    return _row_min(dst, n)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _start(c, dst, acc):  # pragma: no cover - compiled
    """A path's first pixel: its cost, added to acc; the minimum."""
    n = c.shape[0]
    for d in range(n):
        dst[d + 1] = c[d]
        acc[d] += c[d]
    return _row_min(dst, n)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _row_min(row, n):  # pragma: no cover - compiled
    best = _BIG
    for d in range(1, n + 1):
        best = min(best, row[d])
    return best


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _penalty(g, g_prev, p1, p2, tau):  # pragma: no cover - compiled
    """The jump penalty between neighbours of guide values g and g_prev, float32 (no float64 promotion:
    it would turn the disparity loop into double precision)."""
    return max(p1, p2 / (np.float32(1.0) + abs(g - g_prev) / tau))


@nb.njit(cache=True, nogil=True, fastmath=True)
def _pass(cost, out, down, diagonals, p1, p2, guide, tau):  # pragma: no cover - compiled
    """Sum (into ``out``) of the paths of one pass: down (rows top to bottom, x left to right) takes the paths
    arriving from x − 1 in the row, and from the previous row at x (and x − 1, x + 1 with ``diagonals``);
    up the mirror images. Rows of path costs are padded: index 1 + d holds disparity d."""
    h, w, n = cost.shape
    s = 1 if down else -1
    n_rows = 3 if diagonals else 1               # previous-row paths: from x, then x − s and x + s
    prev = np.full((n_rows, w, n + 2), _BIG, np.float32)
    cur = np.full((n_rows, w, n + 2), _BIG, np.float32)
    prev_min = np.zeros((n_rows, w), np.float32)
    cur_min = np.zeros((n_rows, w), np.float32)
    hor = np.full((2, n + 2), _BIG, np.float32)  # the row path: previous pixel, this pixel
    hor_min = np.float32(0.0)
    for iy in range(h):
        y = iy if down else h - 1 - iy
        for ix in range(w):
            x = ix if down else w - 1 - ix
            c = cost[y, x]
            g = guide[y, x]
            acc = out[y, x]
            a = ix & 1                           # the row path's buffers alternate
            if ix == 0:
                hor_min = _start(c, hor[a], acc)
            else:
                jump = hor_min + _penalty(g, guide[y, x - s], p1, p2, tau)
                hor_min = _step(c, hor[1 - a], hor_min, jump, p1, hor[a], acc)
            for k in range(n_rows):
                px = x if k == 0 else (x - s if k == 1 else x + s)
                if iy == 0 or px < 0 or px >= w:
                    cur_min[k, x] = _start(c, cur[k, x], acc)
                else:
                    m = prev_min[k, px]
                    jump = m + _penalty(g, guide[y - s, px], p1, p2, tau)
                    cur_min[k, x] = _step(c, prev[k, px], m, jump, p1, cur[k, x], acc)
        prev, cur = cur, prev
        prev_min, cur_min = cur_min, prev_min


def aggregate(cost: np.ndarray, p1: float, p2: float, n_paths: int = 8, threads: int = 2,
              guide: np.ndarray | None = None, tau: float = 1.0) -> np.ndarray:
    """Sum over ``n_paths`` (4 or 8) of the SGM path costs of ``cost`` (H, W, D), float32 (H, W, D).

    ``p1`` penalises a one-step disparity change between neighbours, ``p2`` (≥ p1) any larger jump, both in
    the cost's units. With ``guide`` (H, W), a jump between neighbours whose guide values differ by g costs
    max(p1, p2 / (1 + g / tau)) instead (``tau`` in the guide's units)."""
    if n_paths not in (4, 8):
        raise ValueError(f"n_paths must be 4 or 8, got {n_paths}")
    if not 0 <= p1 <= p2:
        raise ValueError(f"SGM penalties need 0 <= p1 <= p2, got p1={p1}, p2={p2}")
    if not tau > 0:
        raise ValueError(f"tau must be > 0, got {tau}")
    cost = np.ascontiguousarray(cost, dtype=np.float32)
    if guide is None:
        guide = np.zeros(cost.shape[:2], np.float32)
    guide = np.ascontiguousarray(guide, dtype=np.float32)
    if guide.shape != cost.shape[:2]:
        raise ValueError(f"guide {guide.shape} must match the cost's image size {cost.shape[:2]}")
    outs = [np.zeros_like(cost), np.zeros_like(cost)]
    args = (np.float32(p1), np.float32(p2), guide, np.float32(tau))
    diagonals = n_paths == 8
    if threads < 2:
        for k in range(2):
            _pass(cost, outs[k], k == 0, diagonals, *args)
    else:
        with ThreadPoolExecutor(2) as pool:
            list(pool.map(lambda k: _pass(cost, outs[k], k == 0, diagonals, *args), range(2)))
    total = outs[0]
    total += outs[1]
    return total
