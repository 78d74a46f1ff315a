"""Matched edges: pixel pairs, their disparity and 3-D points."""
from __future__ import annotations

from dataclasses import dataclass, field

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
        return EdgePair(self.left_px, self.right_px, self.disparity_px, self.left_label, self.right_label,
                        self.shape_disparity_px, points_mm)

    def median_z_mm(self) -> float:
        return float(np.nanmedian(self.points_mm[:, 2])) if self.points_mm is not None else float("nan")


def pair_rows(px, left_idx: np.ndarray, right_idx: np.ndarray, d_star: float, tol_px: float = 2.0):
    """Pair each left edge pixel with the right edge pixel of its row closest to u - d_star (within tol).

    ``left_idx`` / ``right_idx`` index ``px`` (EdgePixels). Each right pixel is used at most once.
    Returns (left indices, right indices) of the pairs, row by row.
    """
    lp, rp = [], []
    rv = px.v[right_idx]
    order = np.argsort(rv, kind="stable")
    right_sorted, rv_sorted = right_idx[order], rv[order]
    for v in np.unique(px.v[left_idx]):
        ls = left_idx[px.v[left_idx] == v]
        a, b = np.searchsorted(rv_sorted, v), np.searchsorted(rv_sorted, v, side="right")
        rs = right_sorted[a:b]
        if len(rs) == 0:
            continue
        cost = np.abs((px.u[ls][:, None] - d_star) - px.u[rs][None, :])
        used = np.zeros(len(rs), dtype=bool)
        for i in np.argsort(cost.min(axis=1), kind="stable"):
            c = np.where(used, np.inf, cost[i])
            j = int(np.argmin(c))
            if c[j] <= tol_px:
                used[j] = True
                lp.append(ls[i])
                rp.append(rs[j])
    return np.asarray(lp, dtype=int), np.asarray(rp, dtype=int)
