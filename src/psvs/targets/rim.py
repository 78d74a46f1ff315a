"""A dark circle's rim to sub-pixel: rays from its centre, each read at the half level between *its own*
inside and outside, and an ellipse fitted to them (:func:`refine_circle`).

The rim is where a ray's profile crosses half-way between that ray's inside and outside levels, so a change
of background under half of a circle (the border of the other view's sheet) does not bias it. An ellipse is
fitted to those sub-pixel rim points (rim points far off the fit, where a sheet border runs right along the
rim, are dropped and the ellipse refitted). Blur pulls the half-level contour of a small circle inward by
about sigma^2 / (2 R); sigma is measured from the rim profiles' steepest slopes and the axes are corrected.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: px: how precisely the detector locates one rim point or one ellipse centre in one view: within 0.25 px of
#: the exact projection even where the other view's sheet crosses the circle (tests/targets/test_pattern.py):
#: the noise the circle pattern's and the hand-eye fit's tests allow a centre.
EDGE_PX = 0.25


@dataclass(frozen=True, eq=False)
class Ellipse:
    """centre_px (u, v), semi-axes (a, b) px along its own axes, angle_rad of the a-axis from +u;
    ``background_spread``: how much the level just outside the rim varies around it (10-90 % range over
    the circle's contrast): ~0 on an even ground, ~1 where another view's sheet edge crosses the circle
    (such a centre is biased by a few tenths of a pixel)."""

    centre_px: np.ndarray
    axes_px: tuple[float, float]
    angle_rad: float
    rim_px: np.ndarray  # (K, 2) sub-pixel rim points used for the fit
    background_spread: float = 0.0

    def row_crossings(self, v: float) -> tuple[float, float] | None:
        """(u_left, u_right) where row v crosses the ellipse, or None."""
        a, b = self.axes_px
        c, s = np.cos(self.angle_rad), np.sin(self.angle_rad)
        y = v - self.centre_px[1]
        # ((x c + y s)/a)^2 + ((-x s + y c)/b)^2 = 1, a quadratic in x
        A = c * c / a ** 2 + s * s / b ** 2
        B = 2 * y * (c * s / a ** 2 - c * s / b ** 2)
        C = y * y * (s * s / a ** 2 + c * c / b ** 2) - 1
        disc = B * B - 4 * A * C
        if disc < 0:
            return None
        r = np.sqrt(disc)
        return self.centre_px[0] + (-B - r) / (2 * A), self.centre_px[0] + (-B + r) / (2 * A)



def refine_circle(grey: np.ndarray, centre: np.ndarray, radius: float, rays: int = 64,
                  avoid: np.ndarray | None = None) -> Ellipse:
    """Sub-pixel rim points along ``rays`` rays (per-ray half-level crossing) and a fitted ellipse.
    ``avoid`` (k, 3): other discs (u, v, radius px) nearby; rays whose profile would run into one (within
    2 px of its rim) are not read, so a neighbour neither moves the rim nor counts as an uneven ground."""
    ang = 2 * np.pi * np.arange(rays) / rays
    if avoid is not None and len(avoid):
        clear = _clear_rays(np.asarray(centre, float), radius, ang, np.asarray(avoid, float))
        if clear.sum() >= rays // 4:            # else read them all: the spread will tell the ground is uneven
            ang = ang[clear]
    dr = min(0.05 * radius, 0.25)                        # sample spacing along a ray, px
    rr = np.arange(0.4 * radius, 1.8 * radius + 2.5, dr)
    xs = centre[0] + np.cos(ang)[:, None] * rr[None, :]
    ys = centre[1] + np.sin(ang)[:, None] * rr[None, :]
    prof = _read_along(grey, xs, ys)
    dp = np.diff(prof, axis=1)                          # rising step = dark inside -> bright outside
    win = (rr[:-1] >= 0.6 * radius) & (rr[:-1] <= 1.4 * radius)
    step = int(np.ceil(max(0.15 * radius, 2.0) / dr))    # levels read +-max(0.15 r, 2 px) around the step
    r, ray, widths, levels = _rim_crossings(prof, dp, rr, win, radius, step, dr)
    pts = np.column_stack([centre[0] + r * np.cos(ang[ray]), centre[1] + r * np.sin(ang[ray])])
    if len(pts) < 8:
        raise ValueError(f"circle at ({centre[0]:.1f}, {centre[1]:.1f}) px: too few rim points ({len(pts)}) to fit")
    e = _fit(pts)
    for _ in range(2):  # drop rim points far off the fit (a sheet border crossing the circle), refit
        res = np.abs(_radial_residual(e, pts))
        mad = np.median(res) + 1e-6
        keep = res <= max(3 * 1.4826 * mad, 0.15)
        if keep.all() or keep.sum() < 8:
            break
        pts = pts[keep]
        e = _fit(pts)
    # blur moves the half-level contour of a curved edge toward its centre of curvature by ~ sigma^2 / (2 R)
    # (the blurred disc's indicator is below one half at the true rim); undo it with the measured spread
    sigma2 = float(np.median(widths)) ** 2 if len(widths) else 0.0
    a, b = e.axes_px
    p10, p90 = np.percentile(levels[:, 1], [10, 90])
    spread = float((p90 - p10) / max(np.median(levels[:, 1] - levels[:, 0]), 1e-6))
    return Ellipse(e.centre_px, (a + sigma2 / (2 * a), b + sigma2 / (2 * b)), e.angle_rad, e.rim_px, spread)


def _rim_crossings(prof, dp, rr, win, radius: float, step: int, dr: float):
    """Each ray's rim (profiles ``prof`` (rays, L) at radii ``rr`` (L,), their steps ``dp`` (rays, L - 1)): the
    strong rising step nearest ``radius`` within the window ``win`` (L - 1,), its levels ``step`` samples
    either side, and the half-level crossing between them. Returns the crossing's radius (m,) px and ray
    (m,), and for every ray with a step of 10 grey levels or more its edge spread (px) and (inside, outside)
    levels."""
    d = np.where(win, dp, -np.inf)
    top = d.max(axis=1, keepdims=True)
    peaks = (d >= 0.4 * top) & (d >= np.roll(d, 1, axis=1)) & (d >= np.roll(d, -1, axis=1))
    peaks &= np.isfinite(top) & (top > 0)
    rows = np.flatnonzero(peaks.any(axis=1))
    # the strong step nearest the blob's radius (the first such on a tie)
    k = np.argmin(np.where(peaks[rows], np.abs(rr[:-1] - radius), np.inf), axis=1)
    a, b = np.maximum(k - step, 0), np.minimum(k + 1 + step, len(rr) - 1)
    lo_level, hi_level = prof[rows, a], prof[rows, b]
    strong = hi_level - lo_level >= 10
    rows, k, a, b, lo_level, hi_level = (x[strong] for x in (rows, k, a, b, lo_level, hi_level))
    half = 0.5 * (lo_level + hi_level)
    # edge spread: a step of height D blurred by a Gaussian of sigma rises at most D / (sigma sqrt(2 pi))
    widths = (hi_level - lo_level) / (dp[rows, k] / dr * np.sqrt(2 * np.pi))
    col = np.arange(prof.shape[1])
    above = (col >= a[:, None]) & (col <= b[:, None]) & (prof[rows] >= half[:, None])
    j = np.argmax(above, axis=1)
    cross = above.any(axis=1) & (j > a)
    rows, j, half = rows[cross], j[cross], half[cross]
    p0, p1 = prof[rows, j - 1], prof[rows, j]
    r = rr[j - 1] + (half - p0) / (p1 - p0) * (rr[j] - rr[j - 1])
    return r, rows, widths, np.column_stack([lo_level, hi_level])


def _read_along(grey: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """The image read bilinearly (float32) at (xs, ys), the border replicated: cv2.remap on the window the
    points reach, 2 px wider (the whole image's border where the window meets it), so that a circle's cost
    does not grow with the image."""
    h, w = grey.shape[:2]
    x0 = int(np.clip(np.floor(np.nanmin(xs)) - 2, 0, w - 1))
    x1 = int(np.clip(np.ceil(np.nanmax(xs)) + 3, x0 + 1, w))
    y0 = int(np.clip(np.floor(np.nanmin(ys)) - 2, 0, h - 1))
    y1 = int(np.clip(np.ceil(np.nanmax(ys)) + 3, y0 + 1, h))
    window = np.ascontiguousarray(grey[y0:y1, x0:x1], dtype=np.float32)
    # float32 coordinates less a whole number of pixels are exact: the same sub-pixel fractions as on the whole
    # image (cv2.remap reads them to 1/32 px), hence the same values
    return cv2.remap(window, xs.astype(np.float32) - np.float32(x0), ys.astype(np.float32) - np.float32(y0),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def _clear_rays(centre: np.ndarray, radius: float, ang: np.ndarray, avoid: np.ndarray) -> np.ndarray:
    """Which rays' profiles (out to 1.4 r plus the level window) keep 2 px clear of every disc in ``avoid``."""
    reach = 1.4 * radius + max(0.15 * radius, 2.0)
    d = np.column_stack([np.cos(ang), np.sin(ang)])                 # (rays, 2)
    rel = avoid[:, :2] - centre                                     # (k, 2)
    t = np.clip(rel @ d.T, 0.0, reach)                              # (k, rays): nearest point along the ray
    gap = np.linalg.norm(rel[:, None, :] - t[..., None] * d[None], axis=2) - avoid[:, 2:3]
    return (gap > 2.0).all(axis=0)


def _fit(pts: np.ndarray) -> Ellipse:
    (cx, cy), (w, h), deg = cv2.fitEllipse(pts.astype(np.float32))
    return Ellipse(np.array([cx, cy]), (w / 2, h / 2), np.radians(deg), pts)


def _radial_residual(e: Ellipse, pts: np.ndarray) -> np.ndarray:
    """Approximate distance (px) of points from the ellipse: (normalised radius - 1) * mean semi-axis."""
    c, s = np.cos(e.angle_rad), np.sin(e.angle_rad)
    d = pts - e.centre_px
    x = (d[:, 0] * c + d[:, 1] * s) / e.axes_px[0]
    y = (-d[:, 0] * s + d[:, 1] * c) / e.axes_px[1]
    return (np.hypot(x, y) - 1) * np.mean(e.axes_px)
