"""Semi-global aggregation (Hirschmüller 2008) of a matching-cost volume, in Numba.

The recursion along each path r is  L_r(p, d) = c(p, d) + min(L_r(p−r, d), L_r(p−r, d±1) + P1,
min_k L_r(p−r, k) + P2) − min_k L_r(p−r, k); the aggregated cost is the sum over the paths. With a guide
image I, the jump penalty follows Hirschmüller's intensity-adaptive form, P2 / (1 + |I(p) − I(p−r)| / τ)
(never below P1), so depth edges settle on image edges instead of spreading into the weaker-textured side.
Memory is one line of the path (W × D) per path on top of the (H, W, D) cost and output volumes. Paths run
on two threads.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba as nb
import numpy as np

#: (dy, dx) of the 8 paths; the first 4 are the horizontal and vertical ones used by the fast mode.
PATHS = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))


@nb.njit(cache=True, nogil=True, fastmath=True)
def _aggregate_path(cost, out, dy, dx, p1, p2, guide, tau):  # pragma: no cover - compiled
    h, w, n_d = cost.shape
    prev = np.zeros((w, n_d), np.float32)
    cur = np.zeros((w, n_d), np.float32)
    prev_min = np.zeros(w, np.float32)
    cur_min = np.zeros(w, np.float32)
    for iy in range(h):
        y = iy if dy >= 0 else h - 1 - iy
        for ix in range(w):
            x = ix if dx >= 0 else w - 1 - ix
            px = x - dx
            best = np.float32(np.inf)
            if px < 0 or px >= w or (dy == 0 and ix == 0) or (dy != 0 and iy == 0):
                for d in range(n_d):
                    v = cost[y, x, d]
                    cur[x, d] = v
                    out[y, x, d] += v
                    best = min(best, v)
            else:
                src = cur if dy == 0 else prev
                m = cur_min[px] if dy == 0 else prev_min[px]
                step = abs(guide[y, x] - guide[y - dy, px]) / tau
                jump = m + max(p1, p2 / (1 + step))
                lo = np.float32(np.inf)
                for d in range(n_d):
                    v = src[px, d]
                    hi = src[px, d + 1] + p1 if d + 1 < n_d else np.float32(np.inf)
                    v = min(v, min(lo, hi), jump)
                    lo = src[px, d] + p1
                    v = cost[y, x, d] + v - m
                    cur[x, d] = v
                    out[y, x, d] += v
                    best = min(best, v)
            cur_min[x] = best
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
    paths = PATHS[:n_paths]
    threads = max(1, min(threads, len(paths)))
    outs = [np.zeros_like(cost) for _ in range(threads)]

    def work(k: int) -> None:
        for dy, dx in paths[k::threads]:
            _aggregate_path(cost, outs[k], dy, dx, np.float32(p1), np.float32(p2), guide, np.float32(tau))

    if threads == 1:
        work(0)
    else:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(work, range(threads)))
    total = outs[0]
    for o in outs[1:]:
        total += o
    return total
