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

:func:`winners` is for a caller that only wants each pixel's winner (psvs.dense): a pass adds the other
pass's sums row by row as it sweeps and keeps only the winner, so only one volume of sums is written and
read back instead of two written and both read by a separate pick. One volume: the two passes meet in the
middle (each sweeps its first half of the rows writing sums, then its second half picking; the state of
its paths is kept between the halves). Two volumes: one per thread, downward then upward.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from psvs.dense.fastmath import SAFE_MATH

#: (dy, dx) of the 8 paths; the first 4 are the horizontal and vertical ones used by the fast mode.
PATHS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))
_BIG = np.float32(1e30)   # the padding of a path's row: never the minimum (finite: the kernels use fastmath)


@dataclass(frozen=True, eq=False)
class Penalties:
    """The smoothness terms of the aggregation. ``p1`` penalises a one-step disparity change between
    neighbours, ``p2`` (≥ p1) any larger jump, both in the cost's units; ``n_paths`` 4 or 8 (:data:`PATHS`).
    With ``guide`` (H, W), a jump between neighbours whose guide values differ by g costs
    max(p1, p2 / (1 + g / tau)) instead (``tau`` in the guide's units)."""

    p1: float
    p2: float
    n_paths: int = 8
    guide: np.ndarray | None = None
    tau: float = 1.0


# A pass keeps each path's previous row in a buffer (path, 1 + x, 1 + d): columns 0 and W + 1 stand for
# "outside the image" and rows start as zeros, a zero source with a zero minimum being exactly a path's
# start (L = c), so the loop has no branch for the borders; lags 0 and n + 1 hold a large cost, so the
# loop over disparities has none for its ends.

_INT_BIG = np.int32(2147483647)


# A path's minimum over the disparities is taken as the costs are computed, on their float32 bits read as
# int32: path costs are >= 0, and non-negative floats order as their bits do. An integer minimum
# vectorises; a float one with one accumulator does not.
@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH, inline="always")
def _bits(v):  # pragma: no cover - compiled
    return np.float32(v).view(np.int32)


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH, inline="always")
def _float(b):  # pragma: no cover - compiled
    return np.int32(b).view(np.float32)


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH, inline="always")
def _penalty(g, g_prev, p1, p2, tau):  # pragma: no cover - compiled
    """The jump penalty between neighbours of guide values g and g_prev, float32 (no float64 promotion:
    it would turn the disparity loop into double precision)."""
    return max(p1, p2 / (np.float32(1.0) + abs(g - g_prev) / tau))


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH, inline="always")
def winner(a, n, lowest):  # pragma: no cover - compiled
    """The first index k < n of ``lowest`` (the minimum of the costs ``a`` (>= n,) float32) plus a parabola's
    sub-pixel offset through a[k − 1], a[k], a[k + 1] (within ±0.5, none at the ends): (k, offset)."""
    k = 0
    while k < n - 1 and a[k] != lowest:   # (bounded: a NaN cost equals nothing)
        k += 1
    off = 0.0
    if 0 < k < n - 1:
        c0, c1, c2 = a[k - 1], a[k], a[k + 1]
        den = c0 - 2 * c1 + c2
        if den > 1e-9:
            off = min(0.5, max(-0.5, 0.5 * (c0 - c2) / den))
    return k, off


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH)
def _pick_row(row, below, best, index, n_valid, total):  # pragma: no cover - compiled
    """best[x] = the winner (:func:`winner`, as index + offset) of row[x] + below[x] (W, D) >= 0, and
    index[x] its index; −1 where a sum is negative (a cost was: the integer minimum is then wrong)."""
    for x in range(row.shape[0]):
        a, b, bt = row[x], below[x], _INT_BIG
        for d in range(n_valid):
            v = a[d] + b[d]
            total[d] = v
            bt = min(bt, _bits(v))
        k, off = winner(total, n_valid, _float(bt))
        best[x] = k + off
        index[x] = k if bt >= 0 else -1


@nb.njit(cache=True, nogil=True, fastmath=SAFE_MATH)
def _pass(cost, out, down, diagonals, p1, p2, guide, tau, pick, below, best, index, n_valid, bufs, mins, iy0,  # noqa: PLR0913
          iy1):  # pragma: no cover - compiled
    """Sum (written to ``out[y, x]``) of the paths of one pass over its rows iy0..iy1 − 1 (counted in the
    pass's direction): down (rows top to bottom) takes the paths arriving from x − 1 in the row and from
    the previous row at x (and x − 1, x + 1 with ``diagonals``); up the mirror images. The costs must be
    >= 0. With ``pick``, ``out`` is one row of work space (1, W, D) written over at every row: after each
    row, ``below`` (the other pass's sums, (H, W, D)) is added to it, ``best[y, x]`` gets the winner among
    the first ``n_valid`` lags as index + sub-pixel offset (:func:`_pick_row`) and ``index[y, x]`` its
    index, while the row is still in cache.

    ``bufs`` (2, paths, W + 2, D + 2) and ``mins`` (2, paths, W + 2) hold the paths' previous row: the
    state after row iy is in bufs[(iy + 1) % 2]. A call with iy0 = 0 starts them afresh; a call that goes
    on from iy0 > 0 needs the arrays of the call that ended there.

    Each row is swept twice: first along the row path's direction (for the up pass, right to left) into a
    row of path costs, then left to right for the paths from the previous row, adding that row and
    writing the sums: the long stream through ``out`` runs in ascending order in both passes (a
    descending one runs at half the speed here)."""
    h, w, n = cost.shape
    s = 1 if down else -1
    n_k = 4 if diagonals else 2                  # path k: 0 the row's, 1 from above, 2 from x − s, 3 from x + s
    if iy0 == 0:
        bufs[:] = _BIG
        bufs[0, :, :, 1:n + 1] = 0.0             # the first row's sources ...
        bufs[1, :, 0, 1:n + 1] = 0.0             # ... and the columns outside the image: zero, minimum zero
        bufs[1, :, w + 1, 1:n + 1] = 0.0
        mins[:] = 0.0
    pen = np.empty((n_k, w), np.float32)         # the jump penalty from each path's previous pixel
    total = np.empty(n, np.float32)              # with pick: a pixel's sum of all paths
    for iy in range(iy0, iy1):
        prev, cur = bufs[iy % 2], bufs[(iy + 1) % 2]
        prev_min, cur_min = mins[iy % 2], mins[(iy + 1) % 2]
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
        row = out[min(y, out.shape[0] - 1)]     # with pick, out is one row of work space
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
                    row[x, d] = (cur[0, xb, d + 1] + l1) + (l2 + l3)
                    b1, b2, b3 = min(b1, _bits(l1)), min(b2, _bits(l2)), min(b3, _bits(l3))
                cur_min[2, xb] = _float(b2)
                cur_min[3, xb] = _float(b3)
            else:
                b1 = _INT_BIG
                for d in range(n):
                    l1 = cost[y, x, d] + min(min(prev[1, xb, d], prev[1, xb, d + 2]) + p1,
                                             min(prev[1, xb, d + 1], j1)) - m1
                    cur[1, xb, d + 1] = l1
                    row[x, d] = cur[0, xb, d + 1] + l1
                    b1 = min(b1, _bits(l1))
            cur_min[1, xb] = _float(b1)
        if pick:
            _pick_row(row, below[y], best[y], index[y], n_valid, total)


@nb.njit(cache=True)
def _states(n_passes, diagonals, w, n):  # pragma: no cover - compiled
    """Work space for the path state of ``n_passes`` passes (see :func:`_pass`): bufs (n_passes, 2, paths,
    w + 2, n + 2) and mins (n_passes, 2, paths, w + 2), float32."""
    n_k = 4 if diagonals else 2
    return (np.empty((n_passes, 2, n_k, w + 2, n + 2), np.float32),
            np.empty((n_passes, 2, n_k, w + 2), np.float32))


@nb.njit(cache=True, parallel=True)
def _both_passes(cost, out, work, diagonals, p1, p2, guide, tau):  # pragma: no cover - compiled
    """The downward pass into ``out`` and the upward one into ``work``, one per thread (Numba's pool: a
    Python thread pool started per call ran them at half the speed). The direction is a run-time value:
    a literal one makes Numba compile a specialisation of the pass that runs at half the speed."""
    h, w, n = cost.shape
    none, no_index = np.empty((1, 1), np.float64), np.empty((1, 1), np.int32)
    bufs, mins = _states(2, diagonals, w, n)
    zero = h - h                           # a run-time 0: a literal one compiles another specialisation
    for k in nb.prange(2):
        _pass(cost, out if k == 0 else work, k == 0, diagonals, p1, p2, guide, tau, k < 0, out, none, no_index,
              zero, bufs[k], mins[k], zero, h)


@nb.njit(cache=True, parallel=True)
def _winners_meet(cost, sums, best, index, n_valid, diagonals, p1, p2, guide, tau):  # noqa: PLR0913  # pragma: no cover - compiled
    """The downward and the upward pass on two threads, meeting in the middle: first each sweeps its
    first half of the rows writing its sums into ``sums`` (the down pass the top half, the up pass the
    bottom half), then each sweeps the other half adding the other pass's sums row by row and keeping
    each pixel's winner (best: index + offset; index)."""
    h, w, n = cost.shape
    m = h // 2
    bufs, mins = _states(2, diagonals, w, n)                 # each pass's state, kept between the halves
    rows = np.empty((2, 1, w, n), np.float32)                # each pass's row of sums while picking
    for half in range(2):
        for i in nb.prange(2):
            down, pick = i == 0, half == 1
            first = m if down else h - m
            iy0, iy1 = (0, first) if half == 0 else (first, h)
            _pass(cost, rows[i] if pick else sums, down, diagonals, p1, p2, guide, tau, pick, sums, best, index,
                  n_valid, bufs[i], mins[i], iy0, iy1)


@nb.njit(cache=True, parallel=True)
def _winners_each(costs, sums, best, index, n_valid, diagonals, p1, p2, guide, tau):  # noqa: PLR0913  # pragma: no cover - compiled
    """Each of the two volumes ``costs`` (2, H, W, D) on its own thread: the downward pass's sums into
    ``sums[i]``, then the upward pass, which adds them row by row and keeps each pixel's winner."""
    h, w, n = costs.shape[1:]
    bufs, mins = _states(2, diagonals, w, n)
    rows = np.empty((2, 1, w, n), np.float32)                # the upward pass's row of sums
    zero = h - h                           # a run-time 0: a literal one compiles another specialisation
    for i in nb.prange(2):
        for step in range(2):
            down = step == 0
            _pass(costs[i], sums[i] if down else rows[i], down, diagonals, p1, p2, guide, tau, not down, sums[i],
                  best[i], index[i], n_valid, bufs[i], mins[i], zero, h)


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _add_into(a, b):  # pragma: no cover - compiled
    a1, b1 = a.reshape(-1), b.reshape(-1)
    for i in nb.prange(a1.shape[0]):
        a1[i] += b1[i]


def _checked(pen: Penalties, size: tuple) -> np.ndarray:
    """The guide as contiguous float32 (H, W) = ``size`` (zeros when None) after checking the penalties;
    ValueError naming the first wrong one."""
    n_paths, p1, p2, tau, guide = pen.n_paths, pen.p1, pen.p2, pen.tau, pen.guide
    if n_paths not in (4, 8):
        raise ValueError(f"n_paths must be 4 or 8, got {n_paths}")
    if not 0 <= p1 <= p2:
        raise ValueError(f"SGM penalties need 0 <= p1 <= p2, got p1={p1}, p2={p2}")
    if not tau > 0:
        raise ValueError(f"tau must be > 0, got {tau}")
    guide = np.zeros(size, np.float32) if guide is None else np.ascontiguousarray(guide, dtype=np.float32)
    if guide.shape != tuple(size):
        raise ValueError(f"guide {guide.shape} must match the cost's image size {tuple(size)}")
    return guide


def aggregate(cost: np.ndarray, penalties: Penalties, threads: int = 2, out: np.ndarray | None = None,
              work: np.ndarray | None = None, min_cost: float | None = None):
    """Sum over ``penalties.n_paths`` (4 or 8) of the SGM path costs of ``cost`` (H, W, D) with the
    smoothness terms ``penalties`` (:class:`Penalties`), float32 (H, W, D). ``out`` and ``work`` (float32, the
    cost's shape), when given, are used instead of new volumes (the result is ``out``): a caller that
    aggregates several times reuses them, and fresh memory costs page faults. ``threads`` < 2 runs the
    two passes one after the other. ``min_cost``: a lower bound of the cost when the caller knows one (a
    pass over the volume less); negative costs are shifted to 0 and the result shifted back (each path's
    cost moves with a constant added to every cost). A caller that only wants each pixel's winner needs
    :func:`winners` instead (one volume of sums less)."""
    cost = np.ascontiguousarray(cost, dtype=np.float32)
    guide = _checked(penalties, cost.shape[:2])
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
    if lowest < 0:
        cost = cost - np.float32(lowest)
    args = (np.float32(penalties.p1), np.float32(penalties.p2), guide, np.float32(penalties.tau))
    diagonals = penalties.n_paths == 8
    if threads < 2:
        none, no_index = np.empty((1, 1), np.float64), np.empty((1, 1), np.int32)
        h, w, n = cost.shape
        bufs, mins = _states(1, diagonals, w, n)
        for k in range(2):
            _pass(cost, outs[k], k == 0, diagonals, *args, False, outs[0], none, no_index, 0, bufs[0], mins[0], 0, h)
    else:
        _both_passes(cost, outs[0], outs[1], diagonals, *args)
    _add_into(outs[0], outs[1])
    if lowest < 0:
        outs[0] += np.float32(lowest * penalties.n_paths)
    return outs[0]


def winners(costs: np.ndarray, n_valid: int, penalties: Penalties, sums: np.ndarray | None = None,
            min_cost: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Winner-take-all of the SGM aggregation of one cost volume (H, W, D) or two at once (2, H, W, D),
    costs >= 0, with the smoothness terms ``penalties`` (:class:`Penalties`). For each pixel, the lowest sum
    over the paths among the first ``n_valid`` <= D lags: its index plus a parabola's sub-pixel offset
    (float64, :func:`winner`), and its index (int32), each of the costs' leading shape ((H, W) or (2, H, W)).

    A pass adds the other pass's sums row by row as it sweeps and keeps only the winner, so only one
    volume of sums is written and read back (``sums``, float32, the costs' shape: work space).
    One volume: the two passes run on two threads and meet in the middle (each first sweeps its half of
    the rows writing its sums, then the other half picking). Two volumes: one per thread. ``min_cost``: a
    lower bound of the costs when the caller knows one (a pass over the volumes less)."""
    costs = np.ascontiguousarray(costs, dtype=np.float32)
    if not (costs.ndim == 3 or (costs.ndim == 4 and costs.shape[0] == 2)):
        raise ValueError(f"winners needs one cost volume (H, W, D) or two (2, H, W, D), got shape {costs.shape}")
    if not 1 <= n_valid <= costs.shape[-1]:
        raise ValueError(f"n_valid must lie in 1..{costs.shape[-1]}, got {n_valid}")
    guide = _checked(penalties, costs.shape[-3:-1])
    if sums is None:
        sums = np.empty_like(costs)
    elif sums.shape != costs.shape or sums.dtype != np.float32 or not sums.flags.c_contiguous:
        raise ValueError(f"SGM buffers must be contiguous float32 {costs.shape}, got {sums.dtype} {sums.shape}")
    elif np.shares_memory(sums, costs):
        raise ValueError("SGM buffers must not overlap the cost or each other")
    if (float(np.min(costs)) if min_cost is None else float(min_cost)) < 0:
        raise ValueError("SGM winners need costs >= 0 (shift them by their minimum)")
    best = np.empty(costs.shape[:-1], np.float64)
    index = np.empty(costs.shape[:-1], np.int32)
    kernel = _winners_meet if costs.ndim == 3 else _winners_each
    kernel(costs, sums, best, index, int(n_valid), penalties.n_paths == 8, np.float32(penalties.p1),
           np.float32(penalties.p2), guide, np.float32(penalties.tau))
    if index.min() < 0:
        raise ValueError("SGM winners need costs >= 0 (shift them by their minimum)")
    return best, index
