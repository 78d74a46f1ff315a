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
cost at both ends), so it vectorises. The two passes run on two threads (Numba's).
"""
from __future__ import annotations

import numba as nb
import numpy as np

#: (dy, dx) of the 8 paths; the first 4 are the horizontal and vertical ones used by the fast mode.
PATHS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))
_BIG = np.float32(1e30)   # the padding of a path's row: never the minimum (finite: the kernels use fastmath)


# The kernels index whole arrays (row numbers, then the disparity from a range) instead of taking a view
# per pixel: a view costs reference counting, and a variable offset added to the disparity would bring
# Numba's negative-index wrap-around into the inner loop, which then does not vectorise.

@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _step(cost, y, x, src, ks, xs, m, jump, p1, dst, kd, xd):  # pragma: no cover - compiled
    """One path step: dst[kd, xd, 1 + d] = cost[y, x, d] + min(src[ks, xs, 1 + d], src[ks, xs, d] + p1,
    src[ks, xs, 2 + d] + p1, jump) − m; returns its minimum."""
    n = cost.shape[2]
    for d in range(n):
        near = min(src[ks, xs, d], src[ks, xs, d + 2]) + p1
        dst[kd, xd, d + 1] = cost[y, x, d] + min(near, min(src[ks, xs, d + 1], jump)) - m
    return _row_min(dst, kd, xd, n)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _start(cost, y, x, dst, kd, xd):  # pragma: no cover - compiled
    """A path's first pixel: its cost into dst[kd, xd, 1:]; the minimum."""
    n = cost.shape[2]
    for d in range(n):
        dst[kd, xd, d + 1] = cost[y, x, d]
    return _row_min(dst, kd, xd, n)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _row_min(row, k, x, n):  # pragma: no cover - compiled
    """min(row[k, x, 1:n + 1]) in eight independent lanes (a one-accumulator float minimum does not
    vectorise)."""
    m0 = m1 = m2 = m3 = m4 = m5 = m6 = m7 = _BIG
    d = 1
    while d + 8 <= n + 1:
        m0, m1 = min(m0, row[k, x, d]), min(m1, row[k, x, d + 1])
        m2, m3 = min(m2, row[k, x, d + 2]), min(m3, row[k, x, d + 3])
        m4, m5 = min(m4, row[k, x, d + 4]), min(m5, row[k, x, d + 5])
        m6, m7 = min(m6, row[k, x, d + 6]), min(m7, row[k, x, d + 7])
        d += 8
    while d <= n:
        m0 = min(m0, row[k, x, d])
        d += 1
    return min(min(min(m0, m1), min(m2, m3)), min(min(m4, m5), min(m6, m7)))


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _penalty(g, g_prev, p1, p2, tau):  # pragma: no cover - compiled
    """The jump penalty between neighbours of guide values g and g_prev, float32 (no float64 promotion:
    it would turn the disparity loop into double precision)."""
    return max(p1, p2 / (np.float32(1.0) + abs(g - g_prev) / tau))


@nb.njit(cache=True, nogil=True, fastmath=True)
def _pass(cost, out, down, diagonals, p1, p2, guide, tau):  # pragma: no cover - compiled
    """Sum (written to ``out``, once per pixel) of the paths of one pass: down (rows top to bottom, x left to right) takes the paths
    arriving from x − 1 in the row, and from the previous row at x (and x − 1, x + 1 with ``diagonals``);
    up the mirror images. Rows of path costs are padded: index 1 + d holds disparity d."""
    h, w, n = cost.shape
    s = 1 if down else -1
    n_rows = 3 if diagonals else 1               # previous-row paths: from x, then x − s and x + s
    prev = np.full((n_rows, w, n + 2), _BIG, np.float32)
    cur = np.full((n_rows, w, n + 2), _BIG, np.float32)
    prev_min = np.zeros((n_rows, w), np.float32)
    cur_min = np.zeros((n_rows, w), np.float32)
    hor = np.full((2, 1, n + 2), _BIG, np.float32)   # the row path: previous pixel, this pixel
    hor_min = np.float32(0.0)
    # the jump penalties from each path's previous pixel, computed up front (vectorised divisions):
    # pen[0] for the row path (from x − s), pen[1 + k] for previous-row path k (from y − s and px(k))
    pen = np.empty((n_rows + 1, h, w), np.float32)
    for y in range(h):
        yp = min(max(y - s, 0), h - 1)
        for k in range(n_rows + 1):
            src = guide[y] if k == 0 else guide[yp]
            shift = -s if k in (0, 2) else (s if k == 3 else 0)    # the neighbour's column is x + shift
            row, gy = pen[k, y], guide[y]
            for x in range(w):
                row[x] = _penalty(gy[x], src[min(max(x + shift, 0), w - 1)], p1, p2, tau)
    for iy in range(h):
        y = iy if down else h - 1 - iy
        for ix in range(w):
            x = ix if down else w - 1 - ix
            a = ix & 1                           # the row path's buffers alternate
            if ix == 0:
                hor_min = _start(cost, y, x, hor, a, 0)
            else:
                jump = hor_min + pen[0, y, x]
                hor_min = _step(cost, y, x, hor, 1 - a, 0, hor_min, jump, p1, hor, a, 0)
            for k in range(n_rows):
                px = x if k == 0 else (x - s if k == 1 else x + s)
                if iy == 0 or px < 0 or px >= w:
                    cur_min[k, x] = _start(cost, y, x, cur, k, x)
                else:
                    m = prev_min[k, px]
                    jump = m + pen[1 + k, y, x]
                    cur_min[k, x] = _step(cost, y, x, prev, k, px, m, jump, p1, cur, k, x)
            if diagonals:                        # the pass's sum of paths, written once
                for d in range(n):
                    out[y, x, d] = hor[a, 0, d + 1] + cur[0, x, d + 1] + cur[1, x, d + 1] + cur[2, x, d + 1]
            else:
                for d in range(n):
                    out[y, x, d] = hor[a, 0, d + 1] + cur[0, x, d + 1]
        prev, cur = cur, prev
        prev_min, cur_min = cur_min, prev_min


@nb.njit(cache=True, parallel=True)
def _both_passes(cost, out, work, diagonals, p1, p2, guide, tau):  # pragma: no cover - compiled
    """The downward pass into ``out`` and the upward one into ``work``, one per thread (Numba's pool: a
    Python thread pool started per call ran them at half the speed)."""
    for k in nb.prange(2):
        if k == 0:
            _pass(cost, out, True, diagonals, p1, p2, guide, tau)
        else:
            _pass(cost, work, False, diagonals, p1, p2, guide, tau)


@nb.njit(cache=True, parallel=True, fastmath=True)
def _add_into(a, b):  # pragma: no cover - compiled
    a1, b1 = a.reshape(-1), b.reshape(-1)
    for i in nb.prange(a1.shape[0]):
        a1[i] += b1[i]


def aggregate(cost: np.ndarray, p1: float, p2: float, n_paths: int = 8, threads: int = 2,
              guide: np.ndarray | None = None, tau: float = 1.0, out: np.ndarray | None = None,
              work: np.ndarray | None = None) -> np.ndarray:
    """Sum over ``n_paths`` (4 or 8) of the SGM path costs of ``cost`` (H, W, D), float32 (H, W, D).

    ``p1`` penalises a one-step disparity change between neighbours, ``p2`` (≥ p1) any larger jump, both in
    the cost's units. With ``guide`` (H, W), a jump between neighbours whose guide values differ by g costs
    max(p1, p2 / (1 + g / tau)) instead (``tau`` in the guide's units). ``out`` and ``work`` (float32, the
    cost's shape), when given, are used instead of new volumes (the result is ``out``): a caller that
    aggregates several times reuses them, and fresh memory costs page faults. ``threads`` < 2 runs the
    two passes one after the other."""
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
    outs = []
    for buf in (out, work):
        if buf is None:
            buf = np.empty_like(cost)
        elif buf.shape != cost.shape or buf.dtype != np.float32 or not buf.flags.c_contiguous:
            raise ValueError(f"SGM buffers must be contiguous float32 {cost.shape}, got {buf.dtype} {buf.shape}")
        elif any(np.shares_memory(buf, a) for a in (cost, *outs)):
            raise ValueError("SGM buffers must not overlap the cost or each other")
        outs.append(buf)
    args = (np.float32(p1), np.float32(p2), guide, np.float32(tau))
    diagonals = n_paths == 8
    if threads < 2:
        for k in range(2):
            _pass(cost, outs[k], k == 0, diagonals, *args)
    else:
        _both_passes(cost, outs[0], outs[1], diagonals, *args)
    _add_into(outs[0], outs[1])
    return outs[0]
