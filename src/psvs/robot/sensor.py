"""The PSVS as a seam sensor: a region of interest of the complex image, both groove edges matched with
their twins (the paper's seeded algorithm, section III.3), triangulated, and the seam point fitted.

A V-groove shows as a dark band in each view: its two edges are the plate's bevel tops. The user shows
the groove once, with a pixel inside the band in the left view of the first frame (teaching by showing,
:func:`auto_seed` finds it when no one is at the keyboard); from then on each frame's seeds are the edges
nearest the previous frame's groove centre on the same row.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from psvs._validate import check_count, check_grey, check_pair, check_positive
from psvs.imaging.pipeline import Pipeline, make_pipeline
from psvs.match.correspondence import finish_pairs
from psvs.match.edges import edge_pixels
from psvs.match.seeded import match_seeded
from psvs.optics.illumination import flat_field
from psvs.optics.rig import Rig
from psvs.optics.scale import pixel_scale
from psvs.optics.search_range import disparity_range, rectification_for
from psvs.robot.seam import SeamObservation

#: The seam sensor's image pipeline: the paper's median 3x3 and Roberts cross, with Otsu's threshold in
#: place of the fixed level 92: where one view shows the groove and the other the plate, the complex
#: image sits near 92 (half of each), so a fixed level splits the groove band into fragments.
SEAM_PIPELINE = make_pipeline([{"op": "median", "ksize": 3}, {"op": "threshold", "method": "otsu"},
                               {"op": "roberts"}])


@dataclass(frozen=True)
class SensorParams:
    """Tuning of the seam sensor; lengths in px of the sensor window.

    first_search_px : float
        Until the groove's width is taught, its edges are looked for this far either side of the seed
        (then 1.6 times the taught half width plus 3 px of the paper's camera).
    width_band : (float, float)
        A row shows the groove's full cross-section when its edges are this share of the taught width
        apart (not where the groove starts or ends, its edges closing in).
    twin_jump_px : float
        Largest change of the twin band's disparity from one accepted frame to the next.
    twin_span_px : float
        Each edge's twin is matched within this many px of the twin band's disparity.
    twin_col_px : float
        The twin band's second edge lies within this many px of where the first one puts it.
    line_tol_px : float
        An edge keeps its pixels within this distance of the line fitted to its full-width rows.
    min_rows : int
        Fewest matched rows per edge for a valid frame.

    The lengths are in px of the paper's camera (1130 px per unit tan(angle)): :class:`SeamSensor` scales
    them to its rig's camera (:func:`psvs.optics.scale.pixel_scale`, :meth:`scaled`).
    """

    first_search_px: float = 60.0
    width_band: tuple[float, float] = (0.75, 1.3)
    twin_jump_px: float = 15.0
    twin_span_px: float = 14.0
    twin_col_px: float = 3.0
    line_tol_px: float = 1.5
    min_rows: int = 8

    def __post_init__(self):
        for name in ("first_search_px", "twin_jump_px", "twin_span_px", "twin_col_px", "line_tol_px"):
            check_positive(getattr(self, name), name, "px")
        lo, hi = check_pair(self.width_band, "width_band")
        if not 0 < lo < 1 < hi:
            raise ValueError(f"width_band must satisfy 0 < low < 1 < high, got {self.width_band!r}")
        check_count(self.min_rows, "min_rows", 3)

    def scaled(self, factor: float) -> "SensorParams":
        """The same tuning with its lengths in px times ``factor`` (a camera's pixel scale)."""
        return replace(self, **{k: getattr(self, k) * factor for k in
                                ("first_search_px", "twin_jump_px", "twin_span_px", "twin_col_px", "line_tol_px")})


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


def _nearest_edges(edge_row: np.ndarray, u_c: float, max_px: float):
    cols = np.flatnonzero(edge_row)
    left = cols[(cols < u_c) & (cols >= u_c - max_px)]
    right = cols[(cols > u_c) & (cols <= u_c + max_px)]
    if len(left) == 0 or len(right) == 0:
        return None
    return int(left.max()), int(right.min())


def groove_edges(sides, half_width_px: float, band: tuple[float, float] = SensorParams.width_band,
                  tol_px: float = SensorParams.line_tol_px):
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
    """Groove-edge tracking in the sensor-window images of one run (state: the last accepted groove
    centre and twin disparity, the taught width; :meth:`commit` an observation to track from it).

    Each frame runs the image pipeline once: on its edge map the groove's two edges are found on the row
    nearest the window's middle that shows the groove's full width and its twin band
    (:meth:`_twin_disparity`); each edge is then matched with its twin by the paper's seeded algorithm
    (:func:`psvs.match.seeded.match_seeded`) inside ``twin_span_px`` of that disparity, and the pairs are
    refined to sub-pixel, corrected for the plate's row shift and triangulated with the exact model
    (:func:`psvs.match.correspondence.finish_pairs`).

    Parameters
    ----------
    rig : Rig
        The sensor window's rig (:func:`psvs.optics.window.roi_rig`).
    seed_px : (u, v)
        A pixel inside the left view's groove in the first frame, px (window coordinates).
    near_mm, far_mm : float
        Working depth range (sets the disparities searched).
    params : SensorParams
    pipeline : Pipeline
    """

    def __init__(self, rig: Rig, seed_px, near_mm: float, far_mm: float, params: SensorParams = SensorParams(),
                 pipeline: Pipeline = SEAM_PIPELINE):
        w, h = rig.camera.image_size_px
        u, v = (float(c) for c in seed_px)
        if not (0 <= u < w and 0 <= v < h):
            raise ValueError(f"seed ({u:g}, {v:g}) is outside the {w}x{h} px sensor window")
        self.rig, self.pipeline = rig, pipeline
        self.scale = pixel_scale(rig.camera)
        self.params = params.scaled(self.scale)   # the paper camera's px to this camera's
        self.rect = rectification_for(rig, near_mm, far_mm)     # a build: twins on rectified rows
        self.range_px = disparity_range(rig, near_mm, far_mm, self.rect)
        self.disparity_px: float | None = None
        self.seed_px = self.centre_px = (u, v)
        self.half_width_px: float | None = None

    def measure(self, grey: np.ndarray) -> SeamObservation:
        """Match both groove edges of one window image (H, W) uint8 and triangulate them (exact model)."""
        grey = flat_field(check_grey(grey, "sensor window image"), self.rig.camera)   # the lens's fall-off undone
        edges = self.pipeline.run(grey)
        px = edge_pixels(edges, self.rect)
        found, seen = None, False
        for v in self._rows(grey.shape[0]):
            e = self._groove_on_row(edges[v])
            if e is None:
                continue
            seen = True
            d = self._twin_disparity(grey, px, int(v), *e)
            if d is not None:       # the nearest such row whose twin band is in the window
                found = (e, int(v), d)
                break
        if found is None:
            return SeamObservation.invalid(self.centre_px, "no twin of the groove edges" if seen
                                           else "no groove edges near the track")
        (ua, ub), v, d = found
        span = self.params.twin_span_px
        sides = [self._edge_twins(grey, edges, (u, v), (max(1.0, d - span), d + span), (ua + ub) / 2, u == ua)
                 for u in (ua, ub)]
        sides = groove_edges(sides, (ub - ua) / 2 if self.half_width_px is None else self.half_width_px,
                              self.params.width_band, self.params.line_tol_px)
        if min(len(s) for s in sides) < self.params.min_rows:
            return SeamObservation.invalid(self.centre_px,
                                           f"edge twins matched on fewer than {self.params.min_rows} rows")
        return SeamObservation(True, (sides[0], sides[1]), ((ua + ub) / 2, float(v)), "", d, (ub - ua) / 2)

    @staticmethod
    def _rows(h: int) -> np.ndarray:
        """The window's middle half of rows, nearest the middle first."""
        return np.argsort(np.abs(np.arange(h) - (h - 1) / 2), kind="stable")[: h // 2]

    def _groove_on_row(self, edge_row: np.ndarray) -> tuple[int, int] | None:
        """The edges (u_a, u_b) nearest the last groove centre on one edge-map row, if they show the
        groove's full width (any width before it is taught)."""
        p = self.params
        max_px = p.first_search_px if self.half_width_px is None else 1.6 * self.half_width_px + 3 * self.scale
        e = _nearest_edges(edge_row, self.centre_px[0], max_px)
        if e is None or self.half_width_px is None:
            return e
        return e if p.width_band[0] < (e[1] - e[0]) / (2 * self.half_width_px) < p.width_band[1] else None

    def _edge_twins(self, grey, edges, seed, d_range, centre_u, left_side) -> tuple[np.ndarray, np.ndarray]:
        """One groove edge matched with its twin from ``seed`` (u, v) within ``d_range`` px, sub-pixel and
        triangulated: (left-view pixels (N, 2), points (N, 3) mm) on the edge's own side of the groove's
        centre column, one pixel per row."""
        pair = match_seeded(edges, seed, d_range, rect=self.rect)
        if len(pair) == 0:
            return np.empty((0, 2)), np.empty((0, 3))
        finished = finish_pairs(grey, [pair], self.rig, model="exact", rect=self.rect)
        if not finished:                # no row of it pins a disparity, or none is lit
            return np.empty((0, 2)), np.empty((0, 3))
        pair, = finished
        # where the groove ends in the window, its end joins both edges into one contour: keep this
        # edge's side of the groove centre
        side = pair.left_px[:, 0] < centre_u if left_side else pair.left_px[:, 0] > centre_u
        # a seam edge crosses each row once: rows where the edge runs along the row (where the groove
        # starts or ends) give no usable twin disparity and are dropped
        left_px, pts = pair.left_px[side], pair.points_mm[side]
        v_rows = left_px[:, 1] if self.rect is None else self._rectified_rows(left_px)
        rows, counts = np.unique(np.rint(v_rows), return_counts=True)      # (a build: rectified rows)
        keep = np.isin(np.rint(v_rows), rows[counts == 1]) & np.all(np.isfinite(pts), axis=1)
        return left_px[keep], pts[keep]

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
        d_lo, d_hi = self.range_px
        row_a = np.flatnonzero(rv == va)
        row_b = np.flatnonzero(rv == vb)
        best = None
        for c in row_a:
            d = la - ru[c]
            if not d_lo <= d <= d_hi or pol(px.u[c], px.v[c]) != pol(ua, v):
                continue
            near_b = row_b[np.abs(ru[row_b] - (lb - d)) <= self.params.twin_col_px]
            if not any(pol(px.u[c2], px.v[c2]) == pol(ub, v) for c2 in near_b):
                continue
            cost = 0.0 if self.disparity_px is None else abs(d - self.disparity_px)
            if self.disparity_px is not None and cost > self.params.twin_jump_px:
                continue
            if best is None or cost < best[0]:
                best = (cost, float(d))
        return None if best is None else best[1]


@dataclass(frozen=True)
class SensorSetup:
    """What a run's seam sensor starts from: the sensor window's rig (what the sensor knows: the design or
    a calibrated build, :func:`psvs.optics.window.roi_rig`), the depth range searched (mm), the seed pixel
    inside the left view's groove (None: found on the first frame by :func:`auto_seed`) and the tuning."""

    rig: Rig
    near_mm: float
    far_mm: float
    seed_px: tuple[float, float] | None = None
    params: SensorParams = SensorParams()

    def start(self, first_image: np.ndarray) -> SeamSensor:
        """The sensor, seeded on the run's first window image (H, W) uint8."""
        min_width = max(1, round(6 * pixel_scale(self.rig.camera)))   # 6 px of the paper's camera
        seed = auto_seed(first_image, min_width_px=min_width) if self.seed_px is None else \
            tuple(float(c) for c in self.seed_px)
        return SeamSensor(self.rig, seed, self.near_mm, self.far_mm, self.params)
