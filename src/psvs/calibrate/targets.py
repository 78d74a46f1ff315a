"""Detect the paper's accuracy pattern (Fig. 9: a row of dark circles on a sheet) in a complex image.

Each circle appears twice, once per view. Dark blobs are found with a black-hat transform (closing minus
image), so they stand out on any local background, including where one view's circle lies on the other
view's sheet. Each blob is refined on the grey image: along rays from its centre, the rim is where the
profile crosses half-way between *that ray's* inside and outside levels, so a change of background under
half of a circle (the border of the other view's sheet) does not bias it. An ellipse is fitted to those
sub-pixel rim points (rim points far off the fit, where a sheet border runs right along the rim, are
dropped and the ellipse refitted). Blur pulls the half-level contour of a small circle inward by about
sigma^2 / (2 R); sigma is measured from the rim profiles' steepest slopes and the axes are corrected. The
two views' copies are paired by the rig's geometry (:mod:`psvs.calibrate.pairing`): sorted by u, the first
``count`` belong to the right view only while the copies sit apart (:func:`detect_pattern`).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs._validate import check_grey
from psvs.errors import MeasurementError


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


@dataclass(frozen=True, eq=False)
class PatternDetection:
    """The pattern's circles in each view, ordered by u: left[k] and right[k] are the same circle."""

    left: list[Ellipse]
    right: list[Ellipse]


#: The discs the detector finds: at most this wide (its black-hat kernel) and at least this large in area
#: (smaller blobs are noise), px: a disc whose image lies outside is never detected.
MAX_DIAMETER_PX = 40
MIN_AREA_PX = 12.0


def blob_contours(grey: np.ndarray, max_diameter_px: int = MAX_DIAMETER_PX, min_area_px: float = MIN_AREA_PX):
    """Dark blobs of at least ``min_area_px`` narrower than ``max_diameter_px`` (black-hat, Otsu): list of
    (contour (K, 2) px, area px, roundness 4 pi area / perimeter^2)."""
    k = 2 * (max_diameter_px // 2) + 3
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
    hat = cv2.morphologyEx(grey, cv2.MORPH_BLACKHAT, kernel)
    if hat.max() < 20:
        return []
    _, mask = cv2.threshold(hat, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    # where the other view's card edge crosses a disc, blur leaves a thin low seam in the hat that cuts
    # the disc in two: close 1-2 px seams (discs of a usable target are much farther apart than that)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    out = []
    for c in contours:
        area = cv2.contourArea(c)
        per = cv2.arcLength(c, True)
        if area >= min_area_px and per > 0:
            out.append((c.reshape(-1, 2).astype(np.float64), float(area), float(4 * np.pi * area / per ** 2)))
    return out


def _centre(contour: np.ndarray) -> np.ndarray:
    m = cv2.moments(contour.astype(np.float32).reshape(-1, 1, 2))
    return np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])


def dark_blobs(grey: np.ndarray, max_diameter_px: int = MAX_DIAMETER_PX, min_area_px: float = MIN_AREA_PX):
    """Candidate dark round blobs (:func:`blob_contours`, roundness >= 0.6): list of (centre (2,),
    equivalent radius px)."""
    return [(_centre(c), float(np.sqrt(a / np.pi))) for c, a, r in blob_contours(grey, max_diameter_px, min_area_px)
            if r >= 0.6]


def split_two_discs(contour: np.ndarray) -> tuple[tuple[np.ndarray, float], tuple[np.ndarray, float]] | None:
    """Two overlapping discs' (centre (2,), radius px) from the outline of their union (K, 2) px: a
    least-squares fit of two circles (each outline point to the nearer), started along the outline's long
    axis. None when the outline is one disc (the centres closer than a third of a radius)."""
    from scipy.optimize import least_squares
    p = contour
    m = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - m)
    along, across = (p - m) @ vt[0], (p - m) @ vt[1]
    r0 = 0.5 * float(np.ptp(across))
    half = max(0.5 * float(np.ptp(along)) - r0, 0.2 * r0)
    x0 = np.concatenate([m - half * vt[0], [r0], m + half * vt[0], [r0]])

    def res(x):
        d1 = np.linalg.norm(p - x[:2], axis=1) - x[2]
        d2 = np.linalg.norm(p - x[3:5], axis=1) - x[5]
        return np.where(np.abs(d1) < np.abs(d2), d1, d2)

    x = least_squares(res, x0, loss="soft_l1", f_scale=1.0).x
    if np.linalg.norm(x[:2] - x[3:5]) < min(x[2], x[5]) / 3 or min(x[2], x[5]) <= 0:
        return None
    return (x[:2], float(x[2])), (x[3:5], float(x[5]))


def refine_circle(grey: np.ndarray, centre: np.ndarray, radius: float, rays: int = 64,
                  avoid: np.ndarray | None = None) -> Ellipse:
    """Sub-pixel rim points along ``rays`` rays (per-ray half-level crossing) and a fitted ellipse.
    ``avoid`` (k, 3): other discs (u, v, radius px) nearby; rays whose profile would run into one (within
    2 px of its rim) are not read, so a neighbour neither moves the rim nor counts as an uneven ground."""
    img = np.asarray(grey, dtype=np.float32)
    ang = 2 * np.pi * np.arange(rays) / rays
    if avoid is not None and len(avoid):
        clear = _clear_rays(np.asarray(centre, float), radius, ang, np.asarray(avoid, float))
        if clear.sum() >= rays // 4:            # else read them all: the spread will tell the ground is uneven
            ang = ang[clear]
    dr = min(0.05 * radius, 0.25)                        # sample spacing along a ray, px
    rr = np.arange(0.4 * radius, 1.8 * radius + 2.5, dr)
    xs = centre[0] + np.cos(ang)[:, None] * rr[None, :]
    ys = centre[1] + np.sin(ang)[:, None] * rr[None, :]
    prof = cv2.remap(img, xs.astype(np.float32), ys.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)
    dp = np.diff(prof, axis=1)                          # rising step = dark inside -> bright outside
    win = (rr[:-1] >= 0.6 * radius) & (rr[:-1] <= 1.4 * radius)
    step = int(np.ceil(max(0.15 * radius, 2.0) / dr))    # levels read +-max(0.15 r, 2 px) around the step
    pts, widths, levels = [], [], []
    for i in range(len(ang)):
        d = np.where(win, dp[i], -np.inf)
        top = d.max()
        if not np.isfinite(top) or top <= 0:
            continue
        peaks = np.flatnonzero((d >= 0.4 * top) & (d >= np.roll(d, 1)) & (d >= np.roll(d, -1)))
        if len(peaks) == 0:
            continue
        k = peaks[np.argmin(np.abs(rr[peaks] - radius))]   # the strong step nearest the blob's radius
        a, b = max(k - step, 0), min(k + 1 + step, len(rr) - 1)
        lo_level, hi_level = prof[i, a], prof[i, b]
        if hi_level - lo_level < 10:
            continue
        half = 0.5 * (lo_level + hi_level)
        levels.append((lo_level, hi_level))
        # edge spread: a step of height D blurred by a Gaussian of sigma rises at most D / (sigma sqrt(2 pi))
        widths.append((hi_level - lo_level) / (dp[i, k] / dr * np.sqrt(2 * np.pi)))
        seg = prof[i, a:b + 1]
        j = np.flatnonzero(seg >= half)
        if len(j) == 0 or j[0] == 0:
            continue
        j = a + j[0]
        p0, p1 = prof[i, j - 1], prof[i, j]
        r = rr[j - 1] + (half - p0) / (p1 - p0) * (rr[j] - rr[j - 1])
        pts.append((centre[0] + r * np.cos(ang[i]), centre[1] + r * np.sin(ang[i])))
    pts = np.asarray(pts, dtype=np.float64)
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
    sigma2 = float(np.median(widths)) ** 2 if widths else 0.0
    a, b = e.axes_px
    lo_hi = np.array(levels)
    p10, p90 = np.percentile(lo_hi[:, 1], [10, 90])
    spread = float((p90 - p10) / max(np.median(lo_hi[:, 1] - lo_hi[:, 0]), 1e-6))
    return Ellipse(e.centre_px, (a + sigma2 / (2 * a), b + sigma2 / (2 * b)), e.angle_rad, e.rim_px, spread)


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


def detect_circles(grey: np.ndarray, count: int = 5, max_diameter_px: int = MAX_DIAMETER_PX,
                   min_area_px: float = MIN_AREA_PX) -> list[Ellipse]:
    """The pattern's 2 ``count`` circles (both views, unpaired, ordered by u) in a complex image: dark round
    blobs ``min_area_px`` to ``max_diameter_px`` (:func:`dark_blobs`), refined (:func:`refine_circle`). Where
    a circle of one view overlaps one of the other (a build whose views are turned against each other, a
    pattern wider than the baseline), their union is split in two (:func:`split_two_discs`) when the round
    blobs are too few.

    Raises ValueError naming the problem: blank image, fewer than 2 ``count`` - 1 circles (circles missing or
    the pattern out of view), circles not on one row; MeasurementError for more circles than 2 ``count``
    (the image shows another pattern than the one asked for: the count is checked, never chosen from) or
    exactly one fewer (one view shows a circle the other does not: the views disagree).
    """
    if not isinstance(count, int) or isinstance(count, bool) or count < 2:
        raise ValueError(f"count must be an integer >= 2 (circles in the pattern), got {count!r}")
    grey = check_grey(grey)
    lo, hi, _, _ = cv2.minMaxLoc(grey)
    if hi - lo < 20:
        raise ValueError("image is blank (no contrast): no pattern to find")
    found = blob_contours(grey, max_diameter_px, min_area_px)
    blobs = [(_centre(c), float(np.sqrt(a / np.pi))) for c, a, r in found if r >= 0.6]
    if len(blobs) < 2 * count:
        blobs = _split_merged(found, 2 * count) or blobs
    if len(blobs) > 2 * count:     # more circles than the pattern asked for: not that pattern, nothing to pick
        raise MeasurementError(f"found {len(blobs)} circles, expected {2 * count} ({count} per view): the image "
                               f"shows more circles than the pattern's {count}")
    if len(blobs) == 2 * count - 1:
        raise MeasurementError(f"found {len(blobs)} circles, expected {2 * count} ({count} per view): one view "
                               f"shows a circle the other does not (covered, out of its field, or a blot)")
    if len(blobs) < 2 * count:
        raise ValueError(f"found {len(blobs)} circle(s), expected {2 * count} ({count} per view): a circle is "
                         f"missing or the pattern is partly out of view")
    blobs.sort(key=lambda b: b[0][0])
    circles = [refine_circle(grey, c, r) for c, r in blobs]
    rows = np.array([e.centre_px[1] for e in circles])
    mean_axis = np.mean([np.mean(e.axes_px) for e in circles])
    if np.ptp(rows) > 0.5 * mean_axis + 0.1 * np.ptp([e.centre_px[0] for e in circles]):
        raise ValueError("the circles do not lie along one row: not the accuracy pattern")
    return circles


def _split_merged(found, want: int) -> list | None:
    """Blobs with ``want`` discs when some of ``found`` (:func:`blob_contours`) are two discs of the two
    views overlapping: blobs of 1.15-2.2 times the round blobs' median area, the not-round ones first
    (two discs just touching), then the largest, split in two (:func:`split_two_discs`) until there are
    ``want``; None when that does not give exactly ``want``."""
    singles = [a for _, a, r in found if r >= 0.6]
    if not singles:
        return None
    med = float(np.median(singles))
    merged = sorted((i for i, (_, a, _) in enumerate(found) if 1.15 * med <= a <= 2.2 * med),
                    key=lambda i: (found[i][2] >= 0.6, -found[i][1]))
    count, chosen = len(singles), []
    for i in merged:
        if count >= want:
            break
        chosen.append(i)
        count += 1 if found[i][2] >= 0.6 else 2
    if count != want:
        return None
    out = [(_centre(c), float(np.sqrt(a / np.pi))) for i, (c, a, r) in enumerate(found)
           if r >= 0.6 and i not in chosen]
    for i in chosen:
        two = split_two_discs(found[i][0])
        if two is None:
            return None
        out += list(two)
    return out


def detect_pattern(grey: np.ndarray, count: int = 5, max_diameter_px: int = MAX_DIAMETER_PX,
                   min_area_px: float = MIN_AREA_PX) -> PatternDetection:
    """Find the pattern's ``count`` circles in both views of a complex image (:func:`detect_circles`) and
    split them by u, the first ``count`` the right view: right only where the two copies sit apart, not
    interleaved. A rig pairs them by its geometry instead (:func:`psvs.calibrate.pairing.pair_with_start`,
    :func:`psvs.calibrate.pattern_measure.measure_pattern`)."""
    circles = detect_circles(grey, count, max_diameter_px, min_area_px)
    return PatternDetection(circles[count:], circles[:count])
