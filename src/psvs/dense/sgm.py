"""Semi-global aggregation (Hirschmüller 2008) of a matching-cost volume, in Numba.

The recursion along each path r is  L_r(p, d) = c(p, d) + min(L_r(p−r, d), L_r(p−r, d±1) + P1,
min_k L_r(p−r, k) + P2) − min_k L_r(p−r, k); the aggregated cost is the sum over the paths. With a guide
image I, the jump penalty follows Hirschmüller's intensity-adaptive form, P2 / (1 + |I(p) − I(p−r)| / τ)
(never below P1), so depth edges settle on image edges instead of spreading into the weaker-textured side.

The paths run in two passes, as OpenCV's StereoSGBM does: a downward pass (rows top to bottom, each row
left to right) carries the paths that come from the left, the upper left, above and the upper right; an
upward pass the four opposite ones. Each pass keeps only the previous row of each path (W × D per path)
and writes its sum of paths once per pixel. A row is swept twice: along the row path's own direction,
then left to right for the paths from the previous row, all three in one loop over the disparities that
has no branch and vectorises; that sweep, which reads the cost and writes the sums, runs left to right in
both passes (a descending stream through a volume runs at half the speed here). The two passes run
on two threads (Numba's). The kernels need costs >= 0 (a path's minimum is taken on the float bits as
integers); :func:`aggregate` shifts other costs, which shifts the result by the same amount per path.
"""
from __future__ import annotations

import numba as nb
import numpy as np

#: (dy, dx) of the 8 paths; the first 4 are the horizontal and vertical ones used by the fast mode.
PATHS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))
_BIG = np.float32(1e30)   # the padding of a path's row: never the minimum (finite: the kernels use fastmath)


# A pass keeps each path's previous row in a buffer (path, 1 + x, 1 + d): columns 0 and W + 1 stand for
# "outside the image" and rows start as zeros, a zero source with a zero minimum being exactly a path's
# start (L = c), so the loop has no branch for the borders; lags 0 and n + 1 hold a large cost, so the
# loop over disparities has none for its ends.

_INT_BIG = np.int32(2147483647)


# A path's minimum over the disparities is taken as the costs are computed, on their float32 bits read as
# int32: path costs are >= 0, and non-negative floats order as their bits do. An integer minimum
# vectorises; a float one with one accumulator does not.
@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _bits(v):  # pragma: no cover - compiled
    return np.float32(v).view(np.int32)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _float(b):  # pragma: no cover - compiled
    return np.int32(b).view(np.float32)


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _penalty(g, g_prev, p1, p2, tau):  # pragma: no cover - compiled
    """The jump penalty between neighbours of guide values g and g_prev, float32 (no float64 promotion:
    it would turn the disparity loop into double precision)."""
    return max(p1, p2 / (np.float32(1.0) + abs(g - g_prev) / tau))


@nb.njit(cache=True, nogil=True, fastmath=True)
def _pass(cost, out, down, diagonals, p1, p2, guide, tau):  # pragma: no cover - compiled
    """Sum (written to ``out``, once per pixel) of the paths of one pass: down (rows top to bottom) takes
    the paths arriving from x − 1 in the row and from the previous row at x (and x − 1, x + 1 with
    ``diagonals``); up the mirror images. The costs must be >= 0.

    Each row is swept twice: first along the row path's direction (for the up pass, right to left) into a
    row of path costs, then left to right for the paths from the previous row, adding that row and
    writing the sums: the long stream through ``out`` runs in ascending order in both passes (a
    descending one runs at half the speed here)."""
    h, w, n = cost.shape
    s = 1 if down else -1
    n_k = 4 if diagonals else 2                  # path k: 0 the row's, 1 from above, 2 from x − s, 3 from x + s
    prev = np.full((n_k, w + 2, n + 2), _BIG, np.float32)
    cur = np.full((n_k, w + 2, n + 2), _BIG, np.float32)
    prev[:, :, 1:n + 1] = 0.0                    # the first row's sources ...
    cur[:, 0, 1:n + 1] = 0.0                     # ... and the columns outside the image: zero, minimum zero
    cur[:, w + 1, 1:n + 1] = 0.0
    prev_min = np.zeros((n_k, w + 2), np.float32)
    cur_min = np.zeros((n_k, w + 2), np.float32)
    pen = np.empty((n_k, w), np.float32)         # the jump penalty from each path's previous pixel
    for iy in range(h):
        y = iy if down else h - 1 - iy
        gy, gp = guide[y], guide[min(max(y - s, 0), h - 1)]
        for x in range(w):
            pen[0, x] = _penalty(gy[x], gy[min(max(x - s, 0), w - 1)], p1, p2, tau)
            pen[1, x] = _penalty(gy[x], gp[x], p1, p2, tau)
        if diagonals:
            for x in range(w):
                pen[2, x] = _penalty(gy[x], gp[min(max(x - s, 0), w - 1)], p1, p2, tau)
                pen[3, x] = _penalty(gy[x], gp[min(max(x + s, 0), w - 1)], p1, p2, tau)
        for ix in range(w):                      # the row path, in its own direction, into cur[0]
            x = ix if down else w - 1 - ix
            xb, x0 = x + 1, x + 1 - s            # the buffers' columns: this pixel, the path's previous one
            m0 = cur_min[0, x0]
            j0 = m0 + pen[0, x]
            b0 = _INT_BIG
            for d in range(n):
                l0 = cost[y, x, d] + min(min(cur[0, x0, d], cur[0, x0, d + 2]) + p1, min(cur[0, x0, d + 1], j0)) - m0
                cur[0, xb, d + 1] = l0
                b0 = min(b0, _bits(l0))
            cur_min[0, xb] = _float(b0)
        for x in range(w):                       # the paths from the previous row, left to right
            xb = x + 1
            m1 = prev_min[1, xb]
            j1 = m1 + pen[1, x]
            if diagonals:
                x2, x3 = xb - s, xb + s
                m2, m3 = prev_min[2, x2], prev_min[3, x3]
                j2, j3 = m2 + pen[2, x], m3 + pen[3, x]
                b1 = b2 = b3 = _INT_BIG
                for d in range(n):
                    c = cost[y, x, d]
                    l1 = c + min(min(prev[1, xb, d], prev[1, xb, d + 2]) + p1, min(prev[1, xb, d + 1], j1)) - m1
                    l2 = c + min(min(prev[2, x2, d], prev[2, x2, d + 2]) + p1, min(prev[2, x2, d + 1], j2)) - m2
                    l3 = c + min(min(prev[3, x3, d], prev[3, x3, d + 2]) + p1, min(prev[3, x3, d + 1], j3)) - m3
                    cur[1, xb, d + 1] = l1
                    cur[2, xb, d + 1] = l2
                    cur[3, xb, d + 1] = l3
                    out[y, x, d] = (cur[0, xb, d + 1] + l1) + (l2 + l3)
                    b1, b2, b3 = min(b1, _bits(l1)), min(b2, _bits(l2)), min(b3, _bits(l3))
                cur_min[2, xb] = _float(b2)
                cur_min[3, xb] = _float(b3)
            else:
                b1 = _INT_BIG
                for d in range(n):
                    l1 = cost[y, x, d] + min(min(prev[1, xb, d], prev[1, xb, d + 2]) + p1,
                                             min(prev[1, xb, d + 1], j1)) - m1
                    cur[1, xb, d + 1] = l1
                    out[y, x, d] = cur[0, xb, d + 1] + l1
                    b1 = min(b1, _bits(l1))
            cur_min[1, xb] = _float(b1)
        prev, cur = cur, prev
        prev_min, cur_min = cur_min, prev_min


@nb.njit(cache=True, parallel=True)
def _both_passes(cost, out, work, diagonals, p1, p2, guide, tau):  # pragma: no cover - compiled
    """The downward pass into ``out`` and the upward one into ``work``, one per thread (Numba's pool: a
    Python thread pool started per call ran them at half the speed). The direction is a run-time value:
    a literal one makes Numba compile a specialisation of the pass that runs at half the speed."""
    for k in nb.prange(2):
        _pass(cost, out if k == 0 else work, k == 0, diagonals, p1, p2, guide, tau)


@nb.njit(cache=True, parallel=True, fastmath=True)
def _add_into(a, b):  # pragma: no cover - compiled
    a1, b1 = a.reshape(-1), b.reshape(-1)
    for i in nb.prange(a1.shape[0]):
        a1[i] += b1[i]


def aggregate(cost: np.ndarray, p1: float, p2: float, n_paths: int = 8, threads: int = 2,
              guide: np.ndarray | None = None, tau: float = 1.0, out: np.ndarray | None = None,
              work: np.ndarray | None = None, min_cost: float | None = None, summed: bool = True):
    """Sum over ``n_paths`` (4 or 8) of the SGM path costs of ``cost`` (H, W, D), float32 (H, W, D).

    ``p1`` penalises a one-step disparity change between neighbours, ``p2`` (≥ p1) any larger jump, both in
    the cost's units. With ``guide`` (H, W), a jump between neighbours whose guide values differ by g costs
    max(p1, p2 / (1 + g / tau)) instead (``tau`` in the guide's units). ``out`` and ``work`` (float32, the
    cost's shape), when given, are used instead of new volumes (the result is ``out``): a caller that
    aggregates several times reuses them, and fresh memory costs page faults. ``threads`` < 2 runs the
    two passes one after the other. ``min_cost``: a lower bound of the cost when the caller knows one (a
    pass over the volume less); negative costs are shifted to 0 and the result shifted back (each path's
    cost moves with a constant added to every cost). ``summed=False`` returns the two passes' sums
    (``out``, ``work``) without adding them (a pass over the volumes less, for a reader that adds them as
    it goes, e.g. :func:`psvs.dense.cost.pick`); it needs costs >= 0."""
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
    lowest = float(np.min(cost)) if min_cost is None else float(min_cost)
    if lowest < 0 and not summed:
        raise ValueError("SGM's two passes can be returned unsummed only for costs >= 0")
    if lowest < 0:
        cost = cost - np.float32(lowest)
    args = (np.float32(p1), np.float32(p2), guide, np.float32(tau))
    diagonals = n_paths == 8
    if threads < 2:
        for k in range(2):
            _pass(cost, outs[k], k == 0, diagonals, *args)
    else:
        _both_passes(cost, outs[0], outs[1], diagonals, *args)
    if not summed:
        return outs[0], outs[1]
    _add_into(outs[0], outs[1])
    if lowest < 0:
        outs[0] += np.float32(lowest * n_paths)
    return outs[0]
