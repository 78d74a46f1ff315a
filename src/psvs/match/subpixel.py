"""Sub-pixel refinement of matched edge pixels on the grey image: the edge crossing of each row.

Along the row, near the steepest sample of the horizontal gradient (within +-radius px of the integer
edge pixel), the edge is where the profile crosses half-way between its local low and high levels
(linear interpolation between samples). For a step blurred by any symmetric point spread (box
supersampling, Gaussian optics) that crossing is unbiased; a parabola on the gradient peak is not
("pixel locking"). Rows where the edge runs nearly along the row
(|g_u| small against |g_v|) are ill-conditioned and keep their integer position.
"""
from __future__ import annotations

import cv2
import numpy as np

from psvs.match.pairs import EdgePair


def refine_columns(grey: np.ndarray, px: np.ndarray, radius: int = 2, min_ratio: float = 0.5,
                   with_mask: bool = False):
    """Sub-pixel u of edge points ``px`` (N, 2) (u, v) on ``grey`` (H, W); returns (N, 2) float (and, with
    ``with_mask``, an (N,) bool mask of the points that could be refined)."""
    img = np.asarray(grey, dtype=np.float64)
    h, w = img.shape
    out = np.asarray(px, dtype=float).copy()
    if len(out) == 0:
        return (out, np.zeros(0, bool)) if with_mask else out
    u = np.rint(out[:, 0]).astype(int)
    v = np.rint(out[:, 1]).astype(int)
    n = np.arange(len(u))
    offs = np.arange(-radius - 1, radius + 2)
    cols = np.clip(u[:, None] + offs[None, :], 1, w - 2)
    rows = np.clip(v, 1, h - 2)[:, None]
    prof = img[rows, cols]                                          # (N, 2r+3) row profile
    g = 0.5 * (img[rows, cols + 1] - img[rows, cols - 1])
    gv = 0.5 * (img[np.clip(rows + 1, 0, h - 1), cols] - img[np.clip(rows - 1, 0, h - 1), cols])
    k = np.argmax(np.abs(g[:, 1:-1]), axis=1) + 1                    # steepest sample, not at the ends
    # half-level crossing between the local low and high levels, next to the steepest sample
    half = 0.5 * (prof.min(axis=1) + prof.max(axis=1))
    # the crossing lies between k and k+1 when moving along the step direction reaches half after k
    lo_idx = np.where((prof[n, k] - half) * g[n, k] < 0, k, k - 1)
    p0, p1 = prof[n, lo_idx], prof[n, np.minimum(lo_idx + 1, prof.shape[1] - 1)]
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = (half - p0) / (p1 - p0)
    g0 = np.abs(g[n, k])
    ok = (g0 > 0) & np.isfinite(frac) & (frac >= 0) & (frac <= 1) & (g0 >= min_ratio * np.abs(gv[n, k]))
    ok &= (u >= radius + 2) & (u < w - radius - 2) & (v >= 1) & (v < h - 1)
    out[ok, 0] = cols[n, lo_idx][ok] + frac[ok]
    return (out, ok) if with_mask else out


def _local_mean(u: np.ndarray, v: np.ndarray, values: np.ndarray, weights: np.ndarray, radius: int):
    """Mean of ``values`` (weighted 0/1) over a (2r+1)^2 window around each (u, v); NaN where empty."""
    u0, v0 = u.min() - radius, v.min() - radius
    shape = (v.max() - v0 + radius + 1, u.max() - u0 + radius + 1)
    vs, cs = np.zeros(shape), np.zeros(shape)
    np.add.at(vs, (v - v0, u - u0), values * weights)
    np.add.at(cs, (v - v0, u - u0), weights)
    k = 2 * radius + 1
    vs = cv2.boxFilter(vs, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT)
    cs = cv2.boxFilter(cs, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT)
    c = cs[v - v0, u - u0]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c > 0.5, vs[v - v0, u - u0] / c, np.nan)


def refine_pairs(grey: np.ndarray, pair: EdgePair, radius: int = 2, smooth_px: int = 3,
                 spread_px: int = 10) -> EdgePair:
    """The pair refined to sub-pixel.

    Where both sides refine (the edge crosses the row steeply) they take their sub-pixel columns, and the
    disparity is averaged over the well-conditioned pixels within ``smooth_px`` along the edge (disparity
    is continuous along an edge; this averages out the localisation noise). Where the edge runs nearly
    along the row, a position along the row is ill-defined (and the plate shifts the left view's rows):
    such a pixel takes the mean disparity of the well-conditioned pixels within ``spread_px``. The right
    column is then u_l - d. Pixels with no well-conditioned neighbour keep their integer positions.
    """
    left, ok_l = refine_columns(grey, pair.left_px, radius, with_mask=True)
    right, ok_r = refine_columns(grey, pair.right_px, radius, with_mask=True)
    good = ok_l & ok_r
    disp = left[:, 0] - right[:, 0]
    if good.any():
        left[~good, 0] = np.rint(pair.left_px[~good, 0])
        u, v = np.rint(left[:, 0]).astype(int), np.rint(left[:, 1]).astype(int)
        w = good.astype(float)
        near = _local_mean(u, v, disp, w, smooth_px)
        wide = _local_mean(u, v, disp, w, spread_px)
        new = np.where(np.isfinite(near), near, wide)
        has = np.isfinite(new)
        disp = np.where(has, new, pair.left_px[:, 0] - pair.right_px[:, 0])
        right[:, 0] = np.where(has, left[:, 0] - disp, pair.right_px[:, 0])
        left[~has, 0] = pair.left_px[~has, 0]
    return EdgePair(left, right, left[:, 0] - right[:, 0], pair.left_label, pair.right_label,
                    pair.shape_disparity_px, pair.points_mm)
