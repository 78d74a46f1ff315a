"""Sub-pixel refinement of matched edge pixels on the grey image: the edge crossing of each row.

Along the row, the horizontal gradient g(u) = (I(u+1) - I(u-1)) / 2 peaks where the edge crosses the row;
the peak nearest the integer edge pixel (within +-radius px, same sign as the local step) is refined by
fitting a parabola through the peak and its two neighbours. Rows where the edge runs nearly along the row
(|g_u| small against |g_v|) are ill-conditioned and keep their integer position.
"""
from __future__ import annotations

import numpy as np

from psvs.match.pairs import EdgePair


def refine_columns(grey: np.ndarray, px: np.ndarray, radius: int = 2, min_ratio: float = 0.5) -> np.ndarray:
    """Sub-pixel u of edge points ``px`` (N, 2) (u, v) on ``grey`` (H, W); returns (N, 2) float."""
    img = np.asarray(grey, dtype=np.float64)
    h, w = img.shape
    out = np.asarray(px, dtype=float).copy()
    if len(out) == 0:
        return out
    u = np.rint(out[:, 0]).astype(int)
    v = np.rint(out[:, 1]).astype(int)
    offs = np.arange(-radius - 1, radius + 2)
    cols = np.clip(u[:, None] + offs[None, :], 1, w - 2)
    rows = np.clip(v, 1, h - 2)[:, None]
    g = 0.5 * (img[rows, cols + 1] - img[rows, cols - 1])          # (N, 2r+3)
    gv = 0.5 * (img[np.clip(rows + 1, 0, h - 1), cols] - img[np.clip(rows - 1, 0, h - 1), cols])
    inner = slice(1, -1)
    a = np.abs(g[:, inner])
    k = np.argmax(a, axis=1) + 1                                   # peak index in g (not at the ends)
    n = np.arange(len(u))
    g0, gm, gp = np.abs(g[n, k]), np.abs(g[n, k - 1]), np.abs(g[n, k + 1])
    denom = gm - 2 * g0 + gp
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(denom < 0, 0.5 * (gm - gp) / denom, 0.0)
    ok = (g0 > 0) & (np.abs(delta) <= 0.5) & (g0 >= min_ratio * np.abs(gv[n, k]))
    ok &= (u >= radius + 2) & (u < w - radius - 2) & (v >= 1) & (v < h - 1)
    out[ok, 0] = cols[n, k][ok] + delta[ok]
    return out


def refine_pairs(grey: np.ndarray, pair: EdgePair, radius: int = 2) -> EdgePair:
    """The pair with both sides' columns refined to sub-pixel (and the disparity recomputed)."""
    left = refine_columns(grey, pair.left_px, radius)
    right = refine_columns(grey, pair.right_px, radius)
    return EdgePair(left, right, left[:, 0] - right[:, 0], pair.left_label, pair.right_label,
                    pair.shape_disparity_px, pair.points_mm)
