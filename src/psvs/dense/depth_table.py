"""Depth from disparity on a build's rectified grids through a table of the left view's rays, made once per
calibration.

On a build (:mod:`psvs.dense.build`) a left-grid pixel (u', v') with disparity d pairs with the right-grid
pixel (u' − d, v'). The exact path maps both back to complex-image pixels
(:meth:`~psvs.optics.rectify.Rectification.lookup`), traces them through the optics and meets the two rays
(:func:`psvs.measure.triangulate.triangulate`, ``model="exact"``): about 5 µs a pair, most of it undoing the
lens's distortion and testing the mirrors for occlusion. Of the two rays only one needs that work:

- the right view is a pinhole at its virtual centre C_r (two plane mirrors), and its rectified
  coordinates are that pinhole's projection (:mod:`psvs.optics.rectify`): the ray of (u'_r, v') leaves
  C_r along R'ᵀ ((u'_r − c'_x)/f'_x, (v' − c'_y)/f'_y, 1), in closed form;
- the left view's ray of (u', v') passes through the point Q(u', v') where the pinhole ray from C_l meets
  the depth Z = z_ref (how the left view's rectified coordinates are defined: closed form too), but the M1
  plate bends its direction: (p, q, 1) in the rectified frame, against the pinhole's
  ((u' − c'_x)/f'_x, (v' − c'_y)/f'_y, 1), by a smooth field of a few 1e-4 rad.

So the table holds (p, q) of the exact left rays at nodes every ``step_px`` px over the left grid (each node
mapped back with :meth:`~psvs.optics.rectify.Rectification.to_complex` and traced through the exact optics),
and a pixel's (p, q) is interpolated bilinearly: exact for the pinhole part, which is affine in (u', v'),
so only the plate's smooth bend is approximated. The point is the midpoint of the two rays' closest
approach, as in the exact model. The disparity enters in closed form (no axis of the table runs along d),
and the error is the interpolated direction's, growing as Z²: the node spacing is chosen from the far end of
the table's disparities and checked when the table is built against the exact model at cell centres and
random pixels (:attr:`DepthTable.max_error_mm`, kept under :data:`CHECK_MM`). A whole map goes through in
one pass (:func:`table_cloud`, 35-40 ms for 1.4 M points at 1440 x 1080 on 2 cores): no lists of pixels are
built first.

Which pairs get a point is decided as on the exact path, and where the table cannot vouch for a value the
exact path answers:

- no point where the exact path's lookups fail: the left pixel or its twin outside its view's field (the
  same test on the same remaps, :meth:`~psvs.optics.rectify.Rectification.lookup`);
- no point where the two rays are parallel or meet behind the rig or inside the mirror box (Z at most
  :func:`psvs.optics.mirrors.front_z_mm`, for the midpoint and both closest points);
- the exact path (lookups and ray tracing) for a disparity outside the table's range, and for a pixel or a
  twin whose table cell has a node the exact model rejects (off the sensor, vignetted or occluded): the
  field's border, a cell wide, is never extrapolated.

A cell whose four nodes the exact model accepts is taken as accepted throughout: it is at most 8 px wide,
inside the remaps' field (whose own test is as coarse), and a view's field ends at the images of mirror
edges and of the sensor's edge, straight at that scale: only the corner of an occluding mirror's image could
reach into a cell unseen.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numba as nb
import numpy as np

from psvs._validate import check_points
from psvs.dense.cloud import pixel_cloud
from psvs.dense.fastmath import SAFE_MATH
from psvs.measure.triangulate import Triangulation, triangulate
from psvs.optics.mirrors import front_z_mm
from psvs.optics.project import in_image
from psvs.optics.rectify import Rectification
from psvs.optics.rig import Rig
from psvs.optics.search_range import disparity_range
from psvs.optics.trace import trace_pixels

#: The largest difference (mm, in X, Y or Z) between the table and the exact model over the build's check
#: points; a table that misses it is rebuilt with half the node spacing (down to :data:`MIN_STEP_PX`).
CHECK_MM = 0.002
#: Check points per table (half at cell centres, where bilinear interpolation errs most, half at random).
CHECK_POINTS = 4096
#: Node spacing (px) = STEP_SCALE · (the table's smallest disparity) / b', from :data:`MIN_STEP_PX` to
#: :data:`MAX_STEP_PX`: the interpolation error grows as (spacing / f')² · Z_max², and f' / Z_max = d_min / b'.
STEP_SCALE = 12.0
MAX_STEP_PX, MIN_STEP_PX = 8, 2
#: Disparities (px) added beyond :func:`psvs.optics.search_range.disparity_range` at the far end (small:
#: the error grows as Z²) and at the near end.
FAR_MARGIN_PX, NEAR_MARGIN_PX = 2.0, 8.0

# what the kernel reports per pair
_TABLE, _NONE, _EXACT = 0, 1, 2


@dataclass(frozen=True, eq=False)
class DepthTable:
    """The exact left rays of a build's rectification at nodes (u'_i, v'_j) = (i, j) · step_px over its left
    grid, and which nodes of each view the exact model accepts.

    step_px : int
        Node spacing along u' and v', px.
    slopes : ndarray, shape (nv, nu, 2), float64
        (p, q) of the left view's exact ray through node (i, j): its direction is (p, q, 1) in the
        rectified frame (rows of the rectification's rotation). 0 where the node is rejected.
    cells_left, cells_right : ndarray, shape (nv - 1, nu - 1), bool
        Cells whose four nodes the exact model accepts in the left view, in the right view (the right view's
        grid has the same nodes).
    disparity_px : (float, float)
        The disparities (px) the table answers; others go through the exact path.
    max_error_mm : float
        The largest difference (mm, X, Y or Z) from the exact model over the build's check points.
    """

    step_px: int
    slopes: np.ndarray
    cells_left: np.ndarray
    cells_right: np.ndarray
    disparity_px: tuple[float, float]
    max_error_mm: float

    @property
    def nbytes(self) -> int:
        """Memory the table's arrays take, bytes."""
        return self.slopes.nbytes + self.cells_left.nbytes + self.cells_right.nbytes


def node_counts(size_px: tuple[int, int], step_px: int) -> tuple[int, int]:
    """(nu, nv): nodes along u' and v' covering a rectified grid of ``size_px`` (W', H') every ``step_px``."""
    w, h = size_px
    return max(2, math.ceil((w - 1) / step_px) + 1), max(2, math.ceil((h - 1) / step_px) + 1)


def table_range(rect: Rectification) -> tuple[float, float]:
    """The disparities (px) a table of ``rect`` answers: its working range's
    (:func:`psvs.optics.search_range.disparity_range`) widened by :data:`FAR_MARGIN_PX` and
    :data:`NEAR_MARGIN_PX`."""
    lo, hi = disparity_range(rect.rig, rect.near_mm, rect.far_mm, rect)
    return max(1.0, lo - FAR_MARGIN_PX), hi + NEAR_MARGIN_PX


def build_depth_table(rect: Rectification, disparity_px: tuple[float, float] | None = None,
                      step_px: int | None = None) -> DepthTable:
    """The depth table of a build's rectification (see the module docstring).

    Parameters
    ----------
    rect : Rectification
    disparity_px : (float, float), optional
        The disparities (px) to answer; default :func:`table_range`.
    step_px : int, optional
        Node spacing, px; default from the far end of the range (:data:`STEP_SCALE`), halved until the
        check passes (:data:`CHECK_MM`) or it reaches :data:`MIN_STEP_PX`. Given, it is kept whatever the
        check finds (:attr:`DepthTable.max_error_mm` says what it found).

    Returns
    -------
    DepthTable
    """
    lo, hi = table_range(rect) if disparity_px is None else (float(disparity_px[0]), float(disparity_px[1]))
    if not 0 < lo < hi:
        raise ValueError(f"disparity_px must satisfy 0 < low < high (px), got {disparity_px!r}")
    if step_px is not None and not (isinstance(step_px, (int, np.integer)) and step_px >= 1):
        raise ValueError(f"step_px must be an integer >= 1, got {step_px!r}")
    step = int(step_px) if step_px is not None else _first_step(rect, lo)
    while True:
        table = _nodes(rect, step, (lo, hi))
        error = _check(table, rect)
        if error <= CHECK_MM or step_px is not None or step <= MIN_STEP_PX:
            return replace(table, max_error_mm=error)
        step = max(MIN_STEP_PX, step // 2)


def _first_step(rect: Rectification, d_min_px: float) -> int:
    return int(min(MAX_STEP_PX, max(MIN_STEP_PX, math.floor(STEP_SCALE * d_min_px / rect.baseline_mm))))


def _nodes(rect: Rectification, step: int, d_range: tuple[float, float]) -> DepthTable:
    """The table's nodes traced (:attr:`DepthTable.max_error_mm` left NaN)."""
    nu, nv = node_counts(rect.size_px, step)
    gu, gv = np.meshgrid(np.arange(nu) * float(step), np.arange(nv) * float(step))
    nodes = np.column_stack([gu.ravel(), gv.ravel()])
    slopes, ok_left = _left_slopes(rect, nodes)
    ok_right = _traced(rect, nodes, "right")[1]
    cells = []
    for ok in (ok_left.reshape(nv, nu), ok_right.reshape(nv, nu)):
        cells.append(ok[:-1, :-1] & ok[1:, :-1] & ok[:-1, 1:] & ok[1:, 1:])
    return DepthTable(step, slopes.reshape(nv, nu, 2), cells[0], cells[1], d_range, float("nan"))


def _traced(rect: Rectification, uv_rect: np.ndarray, view: str):
    """The exact rays (frame C) of rectified pixels (N, 2) of one view, and which the exact model accepts
    (the pixel maps to one on the sensor, its ray is neither vignetted nor occluded)."""
    uv = rect.to_complex(uv_rect, view)
    ok = np.all(np.isfinite(uv), axis=1) & in_image(uv, rect.rig)
    rays = trace_pixels(np.where(ok[:, None], uv, 0.0), rect.rig, view)
    return rays, ok & rays.valid


def _left_slopes(rect: Rectification, uv_rect: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(p, q) (N, 2) of the exact left rays of rectified pixels (N, 2), 0 where rejected, and the mask."""
    rays, ok = _traced(rect, uv_rect, "left")
    e = rays.dirs @ rect.rotation.T
    with np.errstate(divide="ignore", invalid="ignore"):
        pq = e[:, :2] / e[:, 2:3]
    ok &= (e[:, 2] > 0) & np.all(np.isfinite(pq), axis=1)
    pq[~ok] = 0.0
    return pq, ok


def _check(table: DepthTable, rect: Rectification) -> float:
    """The largest |table − exact| (mm) over :data:`CHECK_POINTS` pairs the table answers: half at cell
    centres (the worst place for bilinear interpolation), half at random, disparities uniform in 1/d
    (seeded: the same table every time)."""
    rng = np.random.default_rng(0)
    w, h = rect.size_px
    nv, nu = table.cells_left.shape
    n = CHECK_POINTS // 2
    centres = (np.column_stack([rng.integers(0, nu, n), rng.integers(0, nv, n)]) + 0.5) * table.step_px
    spread = rng.uniform(0.0, 1.0, (n, 2)) * [w - 1, h - 1]
    uv = np.minimum(np.concatenate([centres, spread]), [w - 1, h - 1])
    lo, hi = table.disparity_px
    d = 1.0 / rng.uniform(1.0 / hi, 1.0 / lo, len(uv))
    got, status = _evaluate(table, rect, uv, d)
    ask = status == _TABLE
    if not ask.any():
        return 0.0
    want = exact_points(rect, uv[ask], d[ask], mapping="exact")
    if not want.valid.any():
        return 0.0
    return float(np.max(np.abs(got[ask][want.valid] - want.points_mm[want.valid])))


def exact_points(rect: Rectification, uv_rect_px, disparity_px, model: str = "exact", *, rig: Rig | None = None,
                 mapping: str = "lookup") -> Triangulation:
    """The points of left-grid pixels and their disparities by the exact path: each pixel (u', v') and its
    twin (u' − d, v') on the right grid mapped back to complex-image pixels and triangulated with ``model``
    (:func:`psvs.measure.triangulate.triangulate`).

    Parameters
    ----------
    rect : Rectification
    uv_rect_px : array_like, shape (N, 2)
        Left-grid pixels (u', v'), px.
    disparity_px : array_like, shape (N,)
        Rectified disparities u'_l − u'_r, px.
    model : str
        Triangulation model.
    rig : Rig, optional
        The rig to triangulate with (default: ``rect``'s).
    mapping : {'lookup', 'exact'}
        How rectified pixels are mapped back: :meth:`~psvs.optics.rectify.Rectification.lookup` (the remaps,
        within ~1e-3 px: what the dense path has always used) or
        :meth:`~psvs.optics.rectify.Rectification.to_complex` (exact, slower).

    Returns
    -------
    Triangulation
        ``points_mm`` (N, 3) frame C, mm, NaN rows where invalid; ``valid`` (N,).
    """
    uv = check_points(uv_rect_px, "uv_rect_px", 2)
    d = np.asarray(disparity_px, dtype=np.float64)
    if d.shape != (len(uv),):
        raise ValueError(f"disparity_px must have shape ({len(uv)},) like uv_rect_px, got {d.shape}")
    if mapping not in ("lookup", "exact"):
        raise ValueError(f"mapping must be 'lookup' or 'exact', got {mapping!r}")
    back = rect.lookup if mapping == "lookup" else rect.to_complex
    left, right = back(uv, "left"), back(np.column_stack([uv[:, 0] - d, uv[:, 1]]), "right")
    ok = np.all(np.isfinite(left), axis=1) & np.all(np.isfinite(right), axis=1)
    pts = np.full((len(uv), 3), np.nan)
    valid = np.zeros(len(uv), bool)
    if ok.any():
        tri = triangulate(left[ok], right[ok], rect.rig if rig is None else rig, model=model)
        pts[ok], valid[ok] = tri.points_mm, tri.valid
    return Triangulation(pts, valid)


def table_points(table: DepthTable, rect: Rectification, uv_rect_px, disparity_px) -> Triangulation:
    """The points of left-grid pixels and their disparities through ``table`` (the exact model within
    :attr:`DepthTable.max_error_mm`; see the module docstring for what is answered by the exact path).

    Parameters
    ----------
    table : DepthTable
        Built for ``rect`` (:func:`build_depth_table`).
    rect : Rectification
    uv_rect_px : array_like, shape (N, 2)
        Left-grid pixels (u', v'), px.
    disparity_px : array_like, shape (N,)
        Rectified disparities u'_l − u'_r, px.

    Returns
    -------
    Triangulation
        ``points_mm`` (N, 3) frame C, mm, NaN rows where invalid; ``valid`` (N,).
    """
    uv = check_points(uv_rect_px, "uv_rect_px", 2)
    d = np.asarray(disparity_px, dtype=np.float64)
    if d.shape != (len(uv),):
        raise ValueError(f"disparity_px must have shape ({len(uv)},) like uv_rect_px, got {d.shape}")
    _check_table(table, rect)
    pts, status = _evaluate(table, rect, uv, d)
    redo = status == _EXACT
    if redo.any():
        ex = exact_points(rect, uv[redo], d[redo])
        pts[redo] = ex.points_mm
        status[redo] = np.where(ex.valid, _TABLE, _NONE)
    valid = status == _TABLE
    pts[~valid] = np.nan
    return Triangulation(pts, valid)


def table_cloud(table: DepthTable, rect: Rectification, disparity, mask=None) -> tuple:
    """:func:`table_points` of every left-grid pixel of a disparity map with a finite disparity > 0, in one pass
    over the map (no lists of pixels built first).

    Parameters
    ----------
    table : DepthTable
        Built for ``rect``.
    rect : Rectification
    disparity : ndarray, shape (H', W')
        The left map (px), on ``rect``'s left grid.
    mask : ndarray of bool, shape (H', W'), optional
        Only these pixels.

    Returns
    -------
    (points_mm, pixels, depth_mm)
        ``points_mm`` (N, 3) frame C, mm, of the pixels with a point, row by row; ``pixels`` (N, 2) their
        (u', v'); ``depth_mm`` (H', W') their Z, NaN elsewhere.
    """
    d, mask = _map_args(table, rect, disparity, mask)
    if mask is not None and SPARSE_SHARE * mask.size > np.count_nonzero(mask):
        return pixel_cloud(d, mask, lambda uv, dd: table_points(table, rect, uv, dd))
    h, w = d.shape
    out, status = np.empty((h * w, 3)), np.empty(h * w, np.int8)
    _map_kernel(np.ascontiguousarray(d), np.zeros((0, 0), bool) if mask is None else mask, *_kernel_args(table, rect),
                out, status)
    redo, ex = _exact_rest(rect, d, status)
    out[redo] = ex.points_mm
    status[redo] = np.where(ex.valid, _TABLE, _NONE)
    n = int(np.count_nonzero(status == _TABLE))
    pts, uv, depth = np.empty((n, 3)), np.empty((n, 2)), np.empty((h, w))
    _compact(status, out, w, pts, uv, depth)
    return pts, uv, depth


def table_depth(table: DepthTable, rect: Rectification, disparity, mask=None) -> np.ndarray:
    """The depth map of :func:`table_cloud` alone, without its points and pixels: one pass over the map writing Z
    (no (H'·W', 3) work space, which at 2 MP is 50 MB of fresh memory and its page faults on every call).

    Parameters
    ----------
    table : DepthTable
        Built for ``rect``.
    rect : Rectification
    disparity : ndarray, shape (H', W')
        The left map (px), on ``rect``'s left grid.
    mask : ndarray of bool, shape (H', W'), optional
        Only these pixels.

    Returns
    -------
    ndarray, shape (H', W'), float64
        Z (mm, frame C) of each pixel :func:`table_cloud` gives a point, NaN elsewhere.
    """
    d, mask = _map_args(table, rect, disparity, mask)
    h, w = d.shape
    depth, status = np.empty((h, w)), np.empty(h * w, np.int8)
    _depth_kernel(np.ascontiguousarray(d), np.zeros((0, 0), bool) if mask is None else mask,
                  *_kernel_args(table, rect), depth, status)
    redo, ex = _exact_rest(rect, d, status)
    depth.ravel()[redo] = np.where(ex.valid, ex.points_mm[:, 2], np.nan)
    return depth


def _exact_rest(rect: Rectification, d: np.ndarray, status: np.ndarray) -> tuple[np.ndarray, Triangulation]:
    """The flat indices of the map's pixels a kernel left to the exact path (status 2) and their exact points."""
    redo = np.flatnonzero(status == _EXACT)
    v, u = np.divmod(redo, d.shape[1])
    return redo, exact_points(rect, np.column_stack([u, v]).astype(np.float64), d.ravel()[redo].astype(np.float64))


def _map_args(table: DepthTable, rect: Rectification, disparity, mask) -> tuple:
    """The map (H, W) and the mask (contiguous bool, or None) checked against each other and the table."""
    d = np.asarray(disparity)
    if d.ndim != 2:
        raise ValueError(f"disparity map must be (H, W), got shape {d.shape}")
    if mask is not None:
        mask = np.ascontiguousarray(mask, dtype=bool)
        if mask.shape != d.shape:
            raise ValueError(f"mask {mask.shape} must have the map's shape {d.shape}")
    _check_table(table, rect)
    return d, mask


#: A mask that keeps fewer than this share of the map's pixels (a live loop's strided grid: a sixteenth) is
#: triangulated as a list of its pixels: the one-pass kernel's work space is the whole map's (40 MB of fresh
#: memory a frame at 1440x1080), and its time went from 40 to 20 ms a frame, the same points.
SPARSE_SHARE = 0.25


def _check_table(table: DepthTable, rect: Rectification) -> None:
    nu, nv = node_counts(rect.size_px, table.step_px)
    if table.slopes.shape != (nv, nu, 2):
        raise ValueError(f"table must have nodes ({nv}, {nu}) for a rectified grid of {rect.size_px} px every "
                         f"{table.step_px} px, got {table.slopes.shape[:2]}: it was built for another rectification")


def _kernel_args(table: DepthTable, rect: Rectification) -> tuple:
    """The kernels' (maps, tables, rot, centres, consts) of ``table`` on ``rect`` (see :func:`_pair`)."""
    K, R = rect.camera_matrix, rect.rotation
    c_left, c_right = rect.centres_mm["left"], rect.centres_mm["right"]
    lo, hi = table.disparity_px
    consts = np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2], float(table.step_px), lo, hi,
                       rect.z_ref_mm - c_left[2], front_z_mm(rect.rig)])
    centres = np.stack([R @ (c_left - c_right), c_right])
    return ((rect.maps("left")[0], rect.maps("right")[0]), (table.slopes, table.cells_left, table.cells_right),
            np.ascontiguousarray(R), centres, consts)


def _evaluate(table: DepthTable, rect: Rectification, uv: np.ndarray, d: np.ndarray):
    """The kernel on the finite rows: points (N, 3) (unset where not answered) and each row's status."""
    finite = np.isfinite(uv[:, 0]) & np.isfinite(uv[:, 1]) & np.isfinite(d)
    if not finite.all():
        pts, status = np.zeros((len(uv), 3)), np.full(len(uv), _NONE, np.int8)
        if finite.any():
            pts[finite], status[finite] = _evaluate(table, rect, uv[finite], d[finite])
        return pts, status
    pts, status = np.empty((len(uv), 3)), np.empty(len(uv), np.int8)
    _table_kernel(np.ascontiguousarray(uv), np.ascontiguousarray(d), *_kernel_args(table, rect), pts, status)
    return pts, status


@nb.njit(cache=True, inline="always")
def _inside(mu, x, y):  # pragma: no cover - compiled
    """Rectification.lookup's test: (x, y) on the grid and the four remap pixels around it inside the view's
    field (map_u >= 0)."""
    h, w = mu.shape
    if not (x >= 0.0 and x <= w - 1 and y >= 0.0 and y <= h - 1):
        return False
    u0 = int(min(x, w - 1.000001))
    v0 = int(min(y, h - 1.000001))
    return mu[v0, u0] >= 0 and mu[v0, u0 + 1] >= 0 and mu[v0 + 1, u0] >= 0 and mu[v0 + 1, u0 + 1] >= 0


@nb.njit(cache=True, inline="always", fastmath=SAFE_MATH)
def _pair(x, y, dd, maps, tables, rot, centres, consts):  # noqa: PLR0913  # pragma: no cover - compiled
    """One pair: the left-grid pixel (x, y) and its twin x - dd; (status, X, Y, Z): status 0, the point
    (frame C, mm); 1: no point, a lookup fails, parallel rays or a point not beyond the mirror box; 2: the exact
    path must answer (X, Y, Z NaN where the rays were not met). maps: the two views' remap u arrays; tables:
    (slopes, cells_left, cells_right); rot: the rectified axes (rows) in frame C; centres: (C_l − C_r in the
    rectified frame, C_r in frame C); consts: f'_x, f'_y, c'_x, c'_y, step, d_min, d_max, z_ref − C_l,z, the
    mirror box's far reach z."""
    fx, fy, cx, cy, step, d_lo, d_hi, dz_ref, front = (consts[0], consts[1], consts[2], consts[3], consts[4],
                                                      consts[5], consts[6], consts[7], consts[8])
    slopes, cells_l, cells_r = tables
    nv, nu = slopes.shape[0], slopes.shape[1]
    xr = x - dd
    nan = np.nan
    if not (_inside(maps[0], x, y) and _inside(maps[1], xr, y)):
        return 1, nan, nan, nan
    if not (dd >= d_lo and dd <= d_hi):
        return 2, nan, nan, nan
    istep = 1.0 / step
    fu, fv, fr = x * istep, y * istep, xr * istep
    i, j, k = min(int(fu), nu - 2), min(int(fv), nv - 2), min(int(fr), nu - 2)
    if not (cells_l[j, i] and cells_r[j, k]):
        return 2, nan, nan, nan
    a, b = fu - i, fv - j
    w00, w01, w10, w11 = (1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b
    p = w00 * slopes[j, i, 0] + w01 * slopes[j, i + 1, 0] + w10 * slopes[j + 1, i, 0] + (
        w11 * slopes[j + 1, i + 1, 0])          # scalars, not row views: a view costs an atomic refcount
    q = w00 * slopes[j, i, 1] + w01 * slopes[j, i + 1, 1] + w10 * slopes[j + 1, i, 1] + (
        w11 * slopes[j + 1, i + 1, 1])
    # Q: the left pinhole ray's point at Z = z_ref, in the rectified frame with C_r at the origin
    ifx, ify = 1.0 / fx, 1.0 / fy           # products, not quotients: a division is slow
    ax, ay = (x - cx) * ifx, (y - cy) * ify
    t = dz_ref / (rot[0, 2] * ax + rot[1, 2] * ay + rot[2, 2])
    qx, qy, qz = centres[0, 0] + t * ax, centres[0, 1] + t * ay, centres[0, 2] + t
    inl = 1.0 / math.sqrt(p * p + q * q + 1.0)
    lx, ly, lz = p * inl, q * inl, inl
    rx = (xr - cx) * ifx
    inr = 1.0 / math.sqrt(rx * rx + ay * ay + 1.0)
    rx, ry, rz = rx * inr, ay * inr, inr
    # closest approach of Q + s l and 0 + t r (psvs.measure.triangulate's exact model)
    bb = lx * rx + ly * ry + lz * rz
    dl = lx * qx + ly * qy + lz * qz
    er = rx * qx + ry * qy + rz * qz
    den = 1.0 - bb * bb
    if not den > 1e-14:
        return 1, nan, nan, nan
    iden = 1.0 / den
    s, tt = (bb * er - dl) * iden, (er - bb * dl) * iden
    px, py, pz = qx + s * lx, qy + s * ly, qz + s * lz          # on the left ray
    sx, sy, sz = tt * rx, tt * ry, tt * rz                      # on the right ray
    mx, my, mz = 0.5 * (px + sx), 0.5 * (py + sy), 0.5 * (pz + sz)
    z_left = centres[1, 2] + rot[0, 2] * px + rot[1, 2] * py + rot[2, 2] * pz
    z_right = centres[1, 2] + rot[0, 2] * sx + rot[1, 2] * sy + rot[2, 2] * sz
    px, py, pz = (centres[1, 0] + rot[0, 0] * mx + rot[1, 0] * my + rot[2, 0] * mz,
                  centres[1, 1] + rot[0, 1] * mx + rot[1, 1] * my + rot[2, 1] * mz,
                  centres[1, 2] + rot[0, 2] * mx + rot[1, 2] * my + rot[2, 2] * mz)
    return (0 if (pz > front and z_left > front and z_right > front) else 1), px, py, pz


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _table_kernel(uv, d, maps, tables, rot, centres, consts, out, status):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_pair` of each finite pair (uv (N, 2), d (N,)) into out (N, 3) and status (N,)."""
    for n in nb.prange(len(d)):
        status[n], out[n, 0], out[n, 1], out[n, 2] = _pair(uv[n, 0], uv[n, 1], d[n], maps, tables, rot, centres,
                                                           consts)


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _map_kernel(dmap, mask, maps, tables, rot, centres, consts, out, status):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_pair` of each pixel of a disparity map (H, W) with a finite d > 0 (and ``mask``, (H, W) bool,
    or (0, 0): every pixel) into out (H·W, 3) and status (H·W,), 3 for the pixels skipped."""
    h, w = dmap.shape
    every = mask.shape[0] == 0
    for y in nb.prange(h):
        for x in range(w):
            n, dd = y * w + x, np.float64(dmap[y, x])
            if dd > 0.0 and math.isfinite(dd) and (every or mask[y, x]):
                status[n], out[n, 0], out[n, 1], out[n, 2] = _pair(np.float64(x), np.float64(y), dd, maps, tables,
                                                                   rot, centres, consts)
            else:
                status[n] = 3


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _depth_kernel(dmap, mask, maps, tables, rot, centres, consts, depth, status):  # noqa: PLR0913  # pragma: no cover - compiled
    """:func:`_map_kernel` keeping only Z: into depth (H, W) (NaN where status is not 0) and status (H·W,)."""
    h, w = dmap.shape
    every = mask.shape[0] == 0
    for y in nb.prange(h):
        for x in range(w):
            n, dd = y * w + x, np.float64(dmap[y, x])
            s, z = 3, np.nan
            if dd > 0.0 and math.isfinite(dd) and (every or mask[y, x]):
                s, _, _, pz = _pair(np.float64(x), np.float64(y), dd, maps, tables, rot, centres, consts)
                if s == 0:
                    z = pz
            status[n] = s
            depth[y, x] = z


@nb.njit(cache=True, parallel=True)
def _compact(status, out, w, pts, uv, depth):  # pragma: no cover - compiled
    """The pixels of status 0, row by row: their points into pts (N, 3), their (u, v) into uv (N, 2) and Z into
    the depth map (H, W, NaN elsewhere)."""
    h = depth.shape[0]
    start = np.zeros(h + 1, np.int64)
    for y in nb.prange(h):
        c = 0
        for x in range(w):
            c += status[y * w + x] == 0
        start[y + 1] = c
    for y in range(h):
        start[y + 1] += start[y]
    for y in nb.prange(h):
        k = start[y]
        for x in range(w):
            n = y * w + x
            if status[n] == 0:
                pts[k, 0], pts[k, 1], pts[k, 2] = out[n, 0], out[n, 1], out[n, 2]
                uv[k, 0], uv[k, 1] = x, y
                depth[y, x] = out[n, 2]
                k += 1
            else:
                depth[y, x] = np.nan
