"""Sub-pixel refinement of matched edge pixels on the grey image: the edge crossing of each row.

Along the row, near the steepest sample of the horizontal gradient (within +-radius px of the integer
edge pixel), the edge is where the profile crosses half-way between its local low and high levels
(linear interpolation between samples). For a step blurred by any symmetric point spread (box
supersampling, Gaussian optics) that crossing is unbiased; a parabola on the gradient peak is not
("pixel locking"). Rows where the edge runs nearly along the row
(|g_u| small against |g_v|) are ill-conditioned and keep their integer position.
"""
from __future__ import annotations

import numpy as np

from psvs.match.edges import row_step
from psvs.match.pairs import EdgePair, local_mean


def refine_columns(grey: np.ndarray, px: np.ndarray, radius: int = 2, min_ratio: float = 0.5,
                   with_mask: bool = False, sign: np.ndarray | None = None):
    """Sub-pixel u of edge points ``px`` (N, 2) (u, v) on ``grey`` (H, W); returns (N, 2) float (and, with
    ``with_mask``, an (N,) bool mask of the points that could be refined).

    ``sign`` (N,), optional: the way each edge steps along the row (+1 rising, -1 falling, 0 either). The
    steepest sample is then sought among those stepping that way: next to a thin stripe (a sliver of
    background between two overlapping views) the stripe's other, opposite edge may be steeper. The low
    and high levels are taken on their own sides of the steepest sample.
    """
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
    if sign is None:
        score = np.abs(g)
    else:
        sg = np.asarray(sign)[:, None]
        score = np.where(sg == 0, np.abs(g), sg * g)
    k = np.argmax(score[:, 1:-1], axis=1) + 1                        # steepest sample, not at the ends
    # half-level crossing between the local low and high levels, next to the steepest sample; each level
    # from its own side of it (a thin stripe's far side is not this edge's level)
    col = np.arange(prof.shape[1])[None, :]
    rising = (g[n, k] >= 0)[:, None]
    before, after = col <= k[:, None], col >= k[:, None]
    low = np.where(np.where(rising, before, after), prof, np.inf).min(axis=1)
    high = np.where(np.where(rising, after, before), prof, -np.inf).max(axis=1)
    half = 0.5 * (low + high)
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


def _row_steps(grey: np.ndarray, px: np.ndarray) -> np.ndarray:
    """:func:`psvs.match.edges.row_step` at the integer pixels nearest ``px`` (N, 2)."""
    img = np.asarray(grey, dtype=np.float64)
    v = np.clip(np.rint(px[:, 1]).astype(int), 0, img.shape[0] - 1)
    return row_step(img, np.rint(px[:, 0]).astype(int), v)


def refine_pairs(grey: np.ndarray, pair: EdgePair, radius: int = 2, smooth_px: int = 3,
                 spread_px: int = 10, grey_right: np.ndarray | None = None) -> EdgePair:
    """The pair refined to sub-pixel (the right side on ``grey_right`` when given: on a build, the left
    side lives on the left view's rectified image and the right side on the right view's).

    Where both sides refine (the edge crosses the row steeply) they take their sub-pixel columns, and the
    disparity is averaged over the well-conditioned pixels within ``smooth_px`` along the edge (disparity
    is continuous along an edge; this averages out the localisation noise). Where the edge runs nearly
    along the row, a position along the row is ill-defined (and the plate shifts the left view's rows):
    such a pixel takes the mean disparity of the well-conditioned pixels within ``spread_px``. The right
    column is then u_l - d. Pixels with no well-conditioned neighbour keep their integer positions.
    """
    grey_right = grey if grey_right is None else grey_right
    sign = np.sign(_row_steps(grey, pair.left_px) + _row_steps(grey_right, pair.right_px))   # the pair's polarity
    left, ok_l = refine_columns(grey, pair.left_px, radius, with_mask=True, sign=sign)
    right, ok_r = refine_columns(grey_right, pair.right_px, radius, with_mask=True, sign=sign)
    good = ok_l & ok_r
    disp = left[:, 0] - right[:, 0]
    if good.any():
        left[~good, 0] = np.rint(pair.left_px[~good, 0])
        u, v = np.rint(left[:, 0]).astype(int), np.rint(left[:, 1]).astype(int)
        near = local_mean(disp[good], u[good], v[good], u, v, smooth_px)
        wide = local_mean(disp[good], u[good], v[good], u, v, spread_px)
        new = np.where(np.isfinite(near), near, wide)
        has = np.isfinite(new)
        disp = np.where(has, new, pair.left_px[:, 0] - pair.right_px[:, 0])
        right[:, 0] = np.where(has, left[:, 0] - disp, pair.right_px[:, 0])
        left[~has, 0] = pair.left_px[~has, 0]
    return EdgePair(left, right, left[:, 0] - right[:, 0], pair.left_label, pair.right_label,
                    pair.shape_disparity_px, pair.points_mm)
