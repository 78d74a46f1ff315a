"""Matched edges: pixel pairs, their disparity and 3-D points."""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np


@dataclass(frozen=True, eq=False)
class EdgePair:
    """One left-view edge and its right-view twin.

    left_px, right_px : (N, 2) matched (u, v) in the complex image, px (sub-pixel after refinement).
    disparity_px : (N,) u_l - u_r, px.
    left_label, right_label : edge component ids in the edge map.
    shape_disparity_px : the disparity shared by most rows (the paper's shape match), px.
    points_mm : (N, 3) triangulated points (frame C, mm; NaN where invalid), once triangulated.
    """

    left_px: np.ndarray
    right_px: np.ndarray
    disparity_px: np.ndarray
    left_label: int
    right_label: int
    shape_disparity_px: float
    points_mm: np.ndarray | None = field(default=None)

    def __len__(self) -> int:
        return len(self.disparity_px)

    def with_points(self, points_mm: np.ndarray) -> "EdgePair":
        """This pair with its pixels' triangulated ``points_mm`` (N, 3) mm."""
        return EdgePair(self.left_px, self.right_px, self.disparity_px, self.left_label, self.right_label,
                        self.shape_disparity_px, points_mm)

    def median_z_mm(self) -> float:
        """Median depth Z (mm) of the pair's valid points; NaN when it has none (or is not triangulated)."""
        z = np.zeros(0) if self.points_mm is None else self.points_mm[:, 2]
        z = z[np.isfinite(z)]
        return float(np.median(z)) if len(z) else float("nan")


def pair_rows(px, left_idx: np.ndarray, right_idx: np.ndarray, d_star, tol_px: float = 2.0):
    """Pair each left edge pixel with the right edge pixel of its row closest to u - d (within tol).

    ``left_idx`` / ``right_idx`` index ``px`` (EdgePixels; left pixels in their left-view coordinates,
    right pixels in their right-view ones, :attr:`EdgePixels.left_uv`); ``d_star`` is one disparity or one
    per left pixel. Each right pixel is used at most once (the closer left pixel wins). Returns (left
    indices, right indices) of the pairs, in row-major order.
    """
    left_idx, right_idx = np.asarray(left_idx, dtype=int), np.asarray(right_idx, dtype=int)
    if len(left_idx) == 0 or len(right_idx) == 0:
        return np.zeros(0, int), np.zeros(0, int)
    (lu, lv), (ru, rv) = px.left_uv, px.right_uv
    width = int(max(lu.max(), ru.max())) + 2 * int(np.ceil(np.max(np.abs(d_star)))) + 10
    rkey = rv[right_idx] * width + ru[right_idx]
    order = np.argsort(rkey)
    rkey, right_sorted = rkey[order], right_idx[order]
    vl = lv[left_idx]
    target = vl * width + (lu[left_idx] - d_star)
    k = np.searchsorted(rkey, target)
    cand = np.stack([k - 1, np.minimum(k, len(rkey) - 1)])            # the neighbours below and above
    ck = rkey[np.maximum(cand, 0)]
    dist = np.abs(ck - target).astype(np.float64)
    dist[(cand < 0) | (ck // width != vl)] = np.inf                    # off the row
    pick = np.argmin(dist, axis=0)
    n = np.arange(len(left_idx))
    best, cost = cand[pick, n], dist[pick, n]
    keep = cost <= tol_px
    if not keep.any():
        return np.zeros(0, int), np.zeros(0, int)
    li, ri, cost = left_idx[keep], right_sorted[best[keep]], cost[keep]
    if np.bincount(ri).max() <= 1:
        return li, ri
    # each right pixel once: the closest left pixel keeps it
    o = np.lexsort((cost, ri))
    ro = ri[o]
    first = np.concatenate(([True], ro[1:] != ro[:-1]))
    sel = np.sort(o[first])
    return li[sel], ri[sel]


def local_mean(values: np.ndarray, from_u: np.ndarray, from_v: np.ndarray, at_u: np.ndarray, at_v: np.ndarray,
               radius: int) -> np.ndarray:
    """Mean of ``values`` given at pixels (from_u, from_v), over the (2r+1)^2 window around each pixel
    (at_u, at_v); NaN where the window holds none. All integer pixel arrays, (N,) and (M,)."""
    if len(at_u) == 0:
        return np.zeros(0)
    if len(from_u) == 0:
        return np.full(len(at_u), np.nan)
    u0 = min(from_u.min(), at_u.min()) - radius
    v0 = min(from_v.min(), at_v.min()) - radius
    shape = (max(from_v.max(), at_v.max()) - v0 + radius + 1, max(from_u.max(), at_u.max()) - u0 + radius + 1)
    vs, cs = np.zeros(shape), np.zeros(shape)
    np.add.at(vs, (from_v - v0, from_u - u0), values)
    np.add.at(cs, (from_v - v0, from_u - u0), 1.0)
    k = 2 * radius + 1
    vs = cv2.boxFilter(vs, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT)
    cs = cv2.boxFilter(cs, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT)
    c = cs[at_v - v0, at_u - u0]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c > 0.5, vs[at_v - v0, at_u - u0] / c, np.nan)


def grow_pairs(px, left_idx: np.ndarray, right_idx: np.ndarray, d_star: float, tol_px: float = 2.0,
               radius_px: int = 6, max_iter: int = 60, polarity: np.ndarray | None = None):
    """Pair along an edge whose disparity drifts (a surface at a slant): start with the pixels at
    ``d_star`` +- tol, then give each unpaired left pixel the mean disparity of the paired left pixels
    within ``radius_px`` along the edge and pair it at that disparity +- tol, until nothing changes.

    ``polarity`` (one value per edge pixel: -1, 0, +1, the sign of the grey step along the row) rejects
    grown pairs whose two pixels step opposite ways. Returns (left indices, right indices) into ``px``.
    """
    def agree(a, b):
        if polarity is None:
            return np.ones(len(a), dtype=bool)
        pa, pb = polarity[a], polarity[b]
        return (pa == pb) | (pa == 0) | (pb == 0)

    (lu, lv), (ru, rv) = px.left_uv, px.right_uv
    left_idx, right_idx = np.asarray(left_idx, dtype=int), np.asarray(right_idx, dtype=int)
    left_idx = left_idx[(lu[left_idx] >= 0) & (lv[left_idx] >= 0)]        # pixels a view cannot see
    right_idx = right_idx[(ru[right_idx] >= 0) & (rv[right_idx] >= 0)]
    li, ri = pair_rows(px, left_idx, right_idx, d_star, tol_px)
    keep = agree(li, ri)
    li, ri = li[keep], ri[keep]
    if len(li) == 0:
        return li, ri
    paired_l = np.zeros(len(px.u), dtype=bool)
    used_r = np.zeros(len(px.u), dtype=bool)
    paired_l[li] = True
    used_r[ri] = True
    for _ in range(max_iter):
        todo = left_idx[~paired_l[left_idx]]
        if len(todo) == 0:
            break
        d_local = local_mean(lu[li] - ru[ri], lu[li], lv[li], lu[todo], lv[todo], radius_px)
        has = np.isfinite(d_local)
        todo, d_local = todo[has], d_local[has]
        if len(todo) == 0:
            break
        free_r = right_idx[~used_r[right_idx]]
        nl, nr = pair_rows(px, todo, free_r, d_local, tol_px)
        keep = agree(nl, nr)
        nl, nr = nl[keep], nr[keep]
        if len(nl) == 0:
            break
        li, ri = np.concatenate([li, nl]), np.concatenate([ri, nr])
        paired_l[nl] = True
        used_r[nr] = True
        if len(nl) < max(8, 0.01 * len(li)):
            break  # the growth has stalled
    order = np.lexsort((lu[li], lv[li]))
    return li[order], ri[order]
