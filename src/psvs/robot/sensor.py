"""The PSVS as a seam sensor: a region of interest of the complex image, both groove edges matched with
their twins (the paper's seeded algorithm, section III.3), triangulated, and the seam point fitted.

A V-groove shows as a dark band in each view: its two edges are the plate's bevel tops. The user shows
the groove once, with a pixel inside the band in the left view of the first frame (teaching by showing,
:func:`auto_seed` finds it when no one is at the keyboard); from then on each frame's seeds are the edges
nearest the previous frame's groove centre on the same row.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psvs.imaging.pipeline import Pipeline, make_pipeline
from psvs.match.correspondence import MatchParams, match_image
from psvs.match.edges import edge_pixels
from psvs.measure.equations import z_eq12
from psvs.optics.rig import Rig
from psvs.optics.search_range import disparity_range, rectification_for

#: The seam sensor's image pipeline: the paper's median 3x3 and Roberts cross, with Otsu's threshold in
#: place of the fixed level 92: where one view shows the groove and the other the plate, the complex
#: image sits near 92 (half of each), so a fixed level splits the groove band into fragments.
SEAM_PIPELINE = make_pipeline([{"op": "median", "ksize": 3}, {"op": "threshold", "method": "otsu"},
                               {"op": "roberts"}])


def auto_seed(grey: np.ndarray, pipeline: Pipeline = SEAM_PIPELINE, min_width_px: int = 6) -> tuple[float, float]:
    """A pixel inside the left view's groove on the middle row: the image shows the groove twice (one dark
    band per view, where the other view sees plate); the left view's is the one at larger u (disparity
    u_l - u_r > 0). Bands touching the image border are ignored. ValueError when there is none."""
    binary = grey
    for step in pipeline.steps[:-1]:     # the pipeline up to its binarisation
        binary = step(binary)
    row = np.asarray(binary)[grey.shape[0] // 2]
    dark = ~row.astype(bool)
    runs, start = [], None
    for u, d in enumerate(np.append(dark, False)):
        if d and start is None:
            start = u
        elif not d and start is not None:
            if u - start >= min_width_px and start > 0 and u < len(row):
                runs.append((start, u))
            start = None
    if not runs:
        raise ValueError("cannot find the groove: the middle row shows no dark band (give the seed by hand)")
    a, b = max(runs, key=lambda r: (r[0] + r[1]))
    return (a + b - 1) / 2, float(grey.shape[0] // 2)


@dataclass(frozen=True, eq=False)
class SeamObservation:
    """One frame's measurement. ``edges_mm``: the two groove edges' triangulated points, each (N, 3)
    frame C, mm (empty when invalid); ``centre_px``: (u, v) of the groove centre in the left view;
    ``reason``: why the frame is invalid ('' when valid); the twin band's disparity and the groove's
    half width on the seed row, px."""

    valid: bool
    edges_mm: tuple[np.ndarray, np.ndarray]
    centre_px: tuple[float, float]
    reason: str = ""
    disparity_px: float | None = None
    half_width_px: float | None = None


def _nearest_edges(edge_row: np.ndarray, u_c: float, max_px: float):
    cols = np.flatnonzero(edge_row)
    left = cols[(cols < u_c) & (cols >= u_c - max_px)]
    right = cols[(cols > u_c) & (cols <= u_c + max_px)]
    if len(left) == 0 or len(right) == 0:
        return None
    return int(left.max()), int(right.min())


def _groove_edges(sides, half_width_px: float, band=(0.75, 1.3), tol_px: float = 1.5):
    """The two bevel tops' points (each (N, 3) mm) among the contour pixels traced from the seeds.

    Where the groove ends (or starts) in the window, its end outline (the V's end, oblique in the image)
    joins the edges and closes the band over a few rows; on those rows one side's pixels are the outline,
    and the other's may still be its edge (a groove oblique in the image: one edge runs on past the
    other's end). So each edge is fitted by a line u(v) on the rows where the groove shows its full
    cross-section (both edges, their distance within ``band`` of the taught 2 * ``half_width_px``; refitted
    without those more than ``tol_px`` off), and keeps its pixels within ``tol_px`` of that line on any row;
    the outline's are off it. ``sides``:
    ((left-view pixels (N, 2), points (N, 3)) of edge a, the same of edge b)."""
    (pa, xa), (pb, xb) = sides
    ra, rb = np.rint(pa[:, 1]).astype(int), np.rint(pb[:, 1]).astype(int)
    common = np.intersect1d(ra, rb)
    ratio = np.zeros(0)
    if len(common):
        lo, n = common[0], common[-1] - common[0] + 1
        means = []
        for px, r in ((pa, ra), (pb, rb)):          # each edge's mean column per row
            sel = (r >= lo) & (r < lo + n)
            means.append(np.bincount(r[sel] - lo, px[sel, 0], n)[common - lo] /
                         np.bincount(r[sel] - lo, None, n)[common - lo])
        ratio = (means[1] - means[0]) / (2 * half_width_px)
    full = common[(ratio > band[0]) & (ratio < band[1])]
    out = []
    for px, x, r in ((pa, xa, ra), (pb, xb, rb)):
        fit = np.isin(r, full)
        if fit.sum() < 3:
            out.append(x[fit])
            continue
        for _ in range(3):       # the band's last rows toward the end may still be outline: refit without
            line = np.polyfit(px[fit, 1], px[fit, 0], 1)
            on = np.abs(px[:, 0] - np.polyval(line, px[:, 1])) <= tol_px
            if (fit & on).sum() < 3 or np.array_equal(fit & on, fit):
                break
            fit &= on
        out.append(x[on])
    return out[0], out[1]


class SeamSensor:
    """Groove-edge tracking in the ROI images of one run (state: the last accepted groove centre and
    disparity, the taught width; :meth:`commit` an observation to track from it).

    Parameters
    ----------
    rig : Rig
        The ROI rig (:func:`roi_rig`).
    seed_px : (u, v)
        A pixel inside the left view's groove in the first frame, px (ROI coordinates).
    near_mm, far_mm : working depth range (sets the disparities searched).
    min_rows : int
        Fewest matched rows per edge for a valid frame.
    """

    def __init__(self, rig: Rig, seed_px, near_mm: float, far_mm: float, min_rows: int = 8,
                 pipeline: Pipeline = SEAM_PIPELINE):
        w, h = rig.camera.image_size_px
        u, v = (float(c) for c in seed_px)
        if not (0 <= u < w and 0 <= v < h):
            raise ValueError(f"seed ({u:g}, {v:g}) is outside the {w}x{h} px sensor window")
        self.rig, self.near_mm, self.far_mm, self.min_rows = rig, near_mm, far_mm, min_rows
        self.pipeline = pipeline
        self.rect = rectification_for(rig, near_mm, far_mm)     # a build: twins on rectified rows
        self.disparity_px: float | None = None
        self.centre_px = (u, v)
        self.half_width_px: float | None = None

    def measure(self, grey: np.ndarray) -> SeamObservation:
        """Match both groove edges of one ROI image (H, W) uint8 and triangulate them (exact model)."""
        edges = self.pipeline.run(grey)
        h = grey.shape[0]
        u_c = self.centre_px[0]
        max_px = 60.0 if self.half_width_px is None else 1.6 * self.half_width_px + 3
        order = np.argsort(np.abs(np.arange(h) - (h - 1) / 2), kind="stable")
        px = edge_pixels(edges, self.rect)
        found, seen = None, False
        for v in order[: h // 2]:
            e = _nearest_edges(edges[v], u_c, max_px)
            if e is None:
                continue
            # a full groove width (not where the groove starts or ends, with its edges closing in)
            if self.half_width_px is not None and not (0.75 < (e[1] - e[0]) / (2 * self.half_width_px) < 1.3):
                continue
            # the nearest such row whose twin band is in the window (on a build, the twins' rows differ
            # and the window's outer rows hold only one view's part)
            seen = True
            d = self._twin_disparity(grey, px, int(v), *e)
            if d is not None:
                found = (e, int(v))
                break
        if found is None:
            reason = "no twin of the groove edges" if seen else "no groove edges near the track"
            return SeamObservation(False, (np.empty((0, 3)),) * 2, self.centre_px, reason)
        (ua, ub), v = found
        cam = self.rig.camera
        # the depths of disparities d +- 10 px (eq. (12) on sensor coordinates x = u * pitch)
        near, far = (float(z_eq12(max(d + dd, 1.0) * cam.pixel_pitch_mm[0], 0.0, cam.focal_length_mm,
                                  self.rig.mirrors.baseline_mm)) for dd in (10.0, -10.0))
        sides = []
        for u in (ua, ub):
            res = match_image(grey, self.rig, seed_px=(u, v), pipeline=self.pipeline, near_mm=near,
                              far_mm=far, rect=self.rect, params=MatchParams(model="exact"))
            if not res.pairs:
                sides.append((np.empty((0, 2)), np.empty((0, 3))))
                continue
            pair = res.pairs[0]
            # where the groove ends in the window, its end joins both edges into one contour: keep this
            # edge's side of the groove centre
            side = pair.left_px[:, 0] < (ua + ub) / 2 if u == ua else pair.left_px[:, 0] > (ua + ub) / 2
            # a seam edge crosses each row once: rows where the edge runs along the row (where the groove
            # starts or ends) give no usable twin disparity and are dropped
            left_px, pts = pair.left_px[side], pair.points_mm[side]
            v_rows = left_px[:, 1] if self.rect is None else self._rectified_rows(left_px)
            rows, counts = np.unique(np.rint(v_rows), return_counts=True)      # (a build: rectified rows)
            keep = np.isin(np.rint(v_rows), rows[counts == 1]) & np.all(np.isfinite(pts), axis=1)
            sides.append((left_px[keep], pts[keep]))
        sides = _groove_edges(sides, (ub - ua) / 2 if self.half_width_px is None else self.half_width_px)
        if min(len(s) for s in sides) < self.min_rows:
            return SeamObservation(False, (np.empty((0, 3)),) * 2, self.centre_px,
                                   f"edge twins matched on fewer than {self.min_rows} rows")
        return SeamObservation(True, (sides[0], sides[1]), ((ua + ub) / 2, float(v)), "", d, (ub - ua) / 2)

    def _rectified_rows(self, uv: np.ndarray) -> np.ndarray:
        """Rectified rows (N,) of left-view pixels (N, 2), from the rectification's pixel table (nearest
        pixel: the rows are only counted, rounded)."""
        table = self.rect.pixel_table("left")
        h, w = table.shape[:2]
        u = np.clip(np.rint(uv[:, 0]).astype(int), 0, w - 1)
        v = np.clip(np.rint(uv[:, 1]).astype(int), 0, h - 1)
        return table[v, u, 1]

    def commit(self, obs: SeamObservation) -> None:
        """Track from this observation on (call it for the frames the path model accepts)."""
        self.centre_px, self.disparity_px = obs.centre_px, obs.disparity_px
        if self.half_width_px is None:   # taught once: the groove's width is the joint's, it does not drift
            self.half_width_px = obs.half_width_px

    def _twin_disparity(self, grey, px, v, ua, ub):
        """The disparity (px) of the groove's twin band on row v: right-view edges at ua - d and ub - d
        with the same polarities (bright-to-dark, dark-to-bright) as ua and ub; the one nearest the last
        frame's disparity. The seeded algorithm alone may pair a groove edge with the wrong one of the
        twin band's two edges (both lie within the disparity range). On a build, rows and columns are
        those of the rectified views (psvs.optics.rectify): the twins' rows in the window differ.
        ``px``: the frame's edge pixels (:func:`psvs.match.edges.edge_pixels`); None when no twin is found."""
        img = grey.astype(float)
        h, w = img.shape

        def pol(u, row):
            g = img[max(0, row - 1): row + 2].mean(axis=0)
            return np.sign(g[min(w - 1, u + 2)] + g[min(w - 1, u + 1)] - g[max(0, u - 1)] - g[max(0, u - 2)])

        ru, rv = px.right_uv
        if self.rect is None:
            (la, va), (lb, vb) = (ua, v), (ub, v)
        else:
            table = self.rect.pixel_table("left")
            (la, va), (lb, vb) = (np.rint(table[v, u]).astype(int) for u in (ua, ub))
        d_lo, d_hi = disparity_range(self.rig, self.near_mm, self.far_mm, self.rect)
        row_a = np.flatnonzero(rv == va)
        row_b = np.flatnonzero(rv == vb)
        best = None
        for c in row_a:
            d = la - ru[c]
            if not d_lo <= d <= d_hi or pol(px.u[c], px.v[c]) != pol(ua, v):
                continue
            near_b = row_b[np.abs(ru[row_b] - (lb - d)) <= 3]
            if not any(pol(px.u[c2], px.v[c2]) == pol(ub, v) for c2 in near_b):
                continue
            cost = 0.0 if self.disparity_px is None else abs(d - self.disparity_px)
            if self.disparity_px is not None and cost > 15:
                continue
            if best is None or cost < best[0]:
                best = (cost, float(d))
        return None if best is None else best[1]


@dataclass(frozen=True)
class SeamPoint:
    """The seam (groove root) at one frame, base frame: point (3,) mm, unit tangent (3,), groove width mm."""

    point_mm: np.ndarray
    tangent: np.ndarray
    width_mm: float


def fit_seam_point(edge_a: np.ndarray, edge_b: np.ndarray, depth_mm: float, up: np.ndarray) -> SeamPoint:
    """The root of a V-groove from its two edges (each (N, 3) mm, same frame): a quadratic fit of each edge
    along the seam direction (no chord bias on curved seams) evaluated at the middle; the root lies
    ``depth_mm`` below the edges' midpoint along ``up`` (the groove's depth as the joint drawing gives it,
    measured along the torch axis)."""
    mean = np.vstack([edge_a, edge_b]).mean(axis=0)
    # the seam direction: principal axis of both edges, each about its own centre (not across the groove)
    _, _, vt = np.linalg.svd(np.vstack([edge_a - edge_a.mean(axis=0), edge_b - edge_b.mean(axis=0)]),
                             full_matrices=False)
    t = vt[0] * np.sign(vt[0] @ (edge_a[-1] - edge_a[0]) or 1.0)
    fits = []
    for e in (edge_a, edge_b):
        tau = (e - mean) @ t
        deg = 2 if np.ptp(tau) > 3.0 and len(e) >= 6 else 1
        coef = [np.polyfit(tau, e[:, k], deg) for k in range(3)]
        fits.append((np.array([np.polyval(c, 0.0) for c in coef]),
                     np.array([np.polyval(np.polyder(c), 0.0) for c in coef])))
    (pa, da), (pb, db) = fits
    tangent = (da + db) / np.linalg.norm(da + db)
    root = (pa + pb) / 2 - depth_mm * np.asarray(up, float)
    return SeamPoint(root, tangent, float(np.linalg.norm(pa - pb)))
