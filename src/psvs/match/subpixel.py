"""Sub-pixel refinement of matched edge pixels on the grey image: the edge crossing of each row.

Along the row, near the steepest sample of the horizontal gradient (within +-radius px of the integer
edge pixel), the edge is where the profile crosses half-way between its local low and high levels
(linear interpolation between samples). For a step blurred by any symmetric point spread (box
supersampling, Gaussian optics) that crossing is unbiased; a parabola on the gradient peak is not
("pixel locking"). Rows where the edge runs nearly along the row
(|g_u| small against |g_v|) are ill-conditioned and keep their integer position.

A pair's rows are conditioned on the edge's direction over a few pixels (:func:`along_the_rows`), not on one
row's gradient: on a pixelated edge running near the row, the row where it steps down has a steep u-gradient,
yet its crossing moves by dv |g_v / g_u| when the twins' rows differ by dv (the plate shifts the left view's
rows by a fraction of a pixel): on Fig. 5a at 600 mm, 6 px of disparity on a top edge 20 px per row.
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


#: px: the Gaussian over which an edge's direction is taken (the staircase of a pixelated edge averaged out).
DIRECTION_SIGMA_PX = 1.5
#: An edge pins a disparity along its row where it crosses the row at 45 deg or steeper (|g_u| >= |g_v| of the
#: smoothed image): a row offset dv between the twins then moves the crossing by at most dv.
MIN_CROSSING_RATIO = 1.0


def along_the_rows(grey: np.ndarray, px: np.ndarray) -> np.ndarray:
    """(N,) bool: the edge at the pixels ``px`` (N, 2) (u, v) of ``grey`` (H, W) runs nearer the row than
    45 deg (:data:`MIN_CROSSING_RATIO`), by the Sobel gradient of the image smoothed by
    :data:`DIRECTION_SIGMA_PX`: a row crossing there does not pin a column."""
    import cv2
    h, w = grey.shape
    if len(px) == 0:
        return np.zeros(0, dtype=bool)
    u = np.clip(np.rint(px[:, 0]).astype(int), 0, w - 1)
    v = np.clip(np.rint(px[:, 1]).astype(int), 0, h - 1)
    m = int(np.ceil(4 * DIRECTION_SIGMA_PX)) + 2        # only the pixels' box, with the filters' reach
    u0, v0 = max(0, u.min() - m), max(0, v.min() - m)
    box = cv2.GaussianBlur(np.asarray(grey[v0:v.max() + m + 1, u0:u.max() + m + 1], dtype=np.float64), (0, 0),
                           DIRECTION_SIGMA_PX, borderType=cv2.BORDER_REFLECT)
    gu = cv2.Sobel(box, cv2.CV_64F, 1, 0, ksize=3)[v - v0, u - u0]
    gv = cv2.Sobel(box, cv2.CV_64F, 0, 1, ksize=3)[v - v0, u - u0]
    return np.abs(gu) < MIN_CROSSING_RATIO * np.abs(gv)


def _row_steps(grey: np.ndarray, px: np.ndarray) -> np.ndarray:
    """:func:`psvs.match.edges.row_step` at the integer pixels nearest ``px`` (N, 2)."""
    img = np.asarray(grey, dtype=np.float64)
    v = np.clip(np.rint(px[:, 1]).astype(int), 0, img.shape[0] - 1)
    return row_step(img, np.rint(px[:, 0]).astype(int), v)


def refine_pairs(grey: np.ndarray, pair: EdgePair, radius: int = 2, smooth_px: int = 3,
                 spread_px: int = 10, grey_right: np.ndarray | None = None) -> EdgePair:
    """The pair refined to sub-pixel (the right side on ``grey_right`` when given: on a build, the left
    side lives on the left view's rectified image and the right side on the right view's).

    Where both sides refine and the edge crosses the row at 45 deg or steeper on both (:func:`along_the_rows`)
    they take their sub-pixel columns, and the disparity is averaged over these well-conditioned pixels
    within ``smooth_px`` along the edge (disparity is continuous along an edge; this averages out the
    localisation noise). Where the edge runs nearer the row, a position along the row is ill-defined (and
    the plate shifts the left view's rows): such a pixel takes the mean disparity of the well-conditioned
    pixels within ``spread_px``. The right column is then u_l - d. Pixels with no well-conditioned
    neighbour are dropped: the pairing's integer disparity, one for the whole edge, is no measurement of
    theirs (on a slanted object it was 5.5 px off along a near-horizontal arc). The pair may come back
    empty.
    """
    grey_right = grey if grey_right is None else grey_right
    sign = np.sign(_row_steps(grey, pair.left_px) + _row_steps(grey_right, pair.right_px))   # the pair's polarity
    left, ok_l = refine_columns(grey, pair.left_px, radius, with_mask=True, sign=sign)
    right, ok_r = refine_columns(grey_right, pair.right_px, radius, with_mask=True, sign=sign)
    good = ok_l & ok_r & ~along_the_rows(grey, pair.left_px) & ~along_the_rows(grey_right, pair.right_px)
    disp = left[:, 0] - right[:, 0]
    has = np.zeros(len(disp), dtype=bool)
    if good.any():
        left[~good, 0] = np.rint(pair.left_px[~good, 0])
        u, v = np.rint(left[:, 0]).astype(int), np.rint(left[:, 1]).astype(int)
        near = local_mean(disp[good], u[good], v[good], u, v, smooth_px)
        wide = local_mean(disp[good], u[good], v[good], u, v, spread_px)
        disp = np.where(np.isfinite(near), near, wide)
        has = np.isfinite(disp)
        right[:, 0] = left[:, 0] - disp
    left, right = left[has], right[has]
    return EdgePair(left, right, left[:, 0] - right[:, 0], pair.left_label, pair.right_label,
                    pair.shape_disparity_px, None if pair.points_mm is None else pair.points_mm[has])
