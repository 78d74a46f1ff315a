"""Dual rectification of a complex image: one remap per view in which that view's epipolar curves are rows.

On a real build the two views of a point no longer share a row (docs/optics.md, "The rig as built"), and
no single warp of the complex image can fix that: one pixel holds both views, and each view needs its own
warp. So each view gets its own *rectified coordinates* (u', v'): the pinhole projection, through one
rectified camera matrix K' and rotation R' shared by both views, from the view's own centre C_l or C_r.
The rectified x axis runs along C_r - C_l, so a scene point has the same v' in both views and its
rectified disparity u'_l - u'_r = f'_x b' / z' (z' along the rectified axis) is positive and grows as the
point comes closer.

The right view is a pinhole (two reflections) and is rectified exactly at every depth. The left view is
not central: the tilted M1 plate displaces each ray by an amount that depends on its direction (about
0.2 mm across the field for a 3 mm plate), and vertically it behaves like a pinhole slightly behind its
horizontal centre (the plate's astigmatism). A left pixel is therefore mapped through its exact traced
ray's point at depth Z = z_ref, and C_l's height and depth and z_ref are fitted so that the two views'
rows agree over the working range (exact optics: mirrors, plate, lens distortion): the residual is
about 0.03 px (:attr:`Rectification.residual_px`). The horizontal coordinate keeps a sub-pixel error of
the same origin; it moves no row, and every pair is triangulated with the exact model from its
complex-image pixels, so it moves no point either.

A view's remap (rectified -> complex pixel) is exact at the nodes of an 8 px grid and bicubic in between
(under 1e-3 px on a real lens), and the rectified coordinates of every complex-image pixel are tabled
once (:meth:`Rectification.pixel_table`); :func:`rectify` keeps the last few in memory, one per rig and
working range, and :func:`remember` puts one read back from a store (psvs.dense.rig_cache) among them.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import cv2
import numpy as np

from psvs._validate import check_points
from psvs.optics.mirrors import VIEWS, direction_map, virtual_centre
from psvs.optics.project import project_points
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels

_GRID_STEP_PX = 8          # the remaps are exact on this grid, bicubic in between
_MAX_GROWTH = 1.6          # a rectified image may be at most this much wider / taller than the camera's
_KEPT = 8                  # rectifications kept in memory (the most recently used)

# (rig, near_mm, far_mm) -> Rectification, the most recently used last
_MEMORY: OrderedDict = OrderedDict()
_MEMORY_LOCK = threading.Lock()


def needs_rectification(rig: Rig) -> bool:
    """True when the views' rows disagree by more than the plate's sub-pixel shift: a misaligned build or
    a distorting lens. On the paper's geometry with a distortion-free lens the complex image's own rows
    are the epipolar lines (the plate's row shift is corrected per pair, psvs.match.correspondence)."""
    return not rig.as_designed or rig.camera.distorted


@dataclass(frozen=True, eq=False)
class Rectification:
    """The rectified coordinates of both views of one rig.

    rotation : (3, 3) rows are the rectified axes x', y', z' in frame C.
    camera_matrix : (3, 3) K' shared by both views (px).
    centres_mm : {'left', 'right'} -> (3,) the views' centres C_l, C_r in frame C (mm).
    z_ref_mm : depth (frame C) at which left-view rays are taken.
    size_px : (width, height) of a rectified image, covering both views' whole field.
    residual_px : largest |v'_l - v'_r| of the fit samples over the working range (px).
    near_mm, far_mm : the working range the fit covers.
    """

    rig: Rig
    rotation: np.ndarray
    camera_matrix: np.ndarray
    centres_mm: dict
    z_ref_mm: float
    size_px: tuple[int, int]
    residual_px: float
    near_mm: float
    far_mm: float
    _maps: dict = field(default_factory=dict, repr=False)
    _tables: dict = field(default_factory=dict, repr=False)
    _fixed: dict = field(default_factory=dict, repr=False)

    @property
    def baseline_mm(self) -> float:
        return float(np.linalg.norm(self.centres_mm["right"] - self.centres_mm["left"]))

    def _pinhole(self, points_mm: np.ndarray, view: str) -> np.ndarray:
        q = (points_mm - self.centres_mm[view]) @ self.rotation.T
        K = self.camera_matrix
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.column_stack([K[0, 0] * q[:, 0] / q[:, 2] + K[0, 2], K[1, 1] * q[:, 1] / q[:, 2] + K[1, 2]])

    def to_rectified(self, uv_px, view: str) -> np.ndarray:
        """Rectified (u', v') (N, 2) of complex-image pixels (N, 2) of one view (exact optics; NaN where the
        pixel's ray is vignetted)."""
        uv = check_points(uv_px, "uv_px", 2)
        rays = trace_pixels(uv, self.rig, _check_view(view))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (self.z_ref_mm - rays.origins_mm[:, 2]) / rays.dirs[:, 2]
        out = self._pinhole(rays.origins_mm + t[:, None] * rays.dirs, view)
        out[~rays.valid | ~(t > 0)] = np.nan
        return out

    def rays(self, uv_rect, view: str) -> np.ndarray:
        """Points (N, 3) mm where rectified pixels' rays from the view's centre meet depth z_ref."""
        uv = check_points(uv_rect, "uv_rect", 2)
        K = self.camera_matrix
        d = np.column_stack([(uv[:, 0] - K[0, 2]) / K[0, 0], (uv[:, 1] - K[1, 2]) / K[1, 1], np.ones(len(uv))])
        d = d @ self.rotation                                  # into frame C
        c = self.centres_mm[_check_view(view)]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (self.z_ref_mm - c[2]) / d[:, 2]
        return c + t[:, None] * d

    def to_complex(self, uv_rect, view: str) -> np.ndarray:
        """Complex-image pixels (N, 2) of rectified pixels (N, 2) of one view, exact (the inverse of
        :meth:`to_rectified`; NaN where no pixel of the view sees that ray)."""
        uv, ok = project_points(self.rays(uv_rect, view), self.rig, view)
        uv[~ok] = np.nan
        return uv

    def pixel_table(self, view: str) -> np.ndarray:
        """Rectified (u', v') of every complex-image pixel of one view, (H, W, 2) float64 (NaN where the
        pixel's ray is vignetted): :meth:`to_rectified` once per rig, a lookup per frame."""
        view = _check_view(view)
        if view not in self._tables:
            w, h = self.rig.camera.image_size_px
            uu, vv = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
            self._tables[view] = self.to_rectified(np.column_stack([uu.ravel(), vv.ravel()]), view).reshape(h, w, 2)
        return self._tables[view]

    def lookup(self, uv_rect, view: str) -> np.ndarray:
        """Complex-image pixels (N, 2) of rectified pixels (N, 2), read from the view's remap by bilinear
        interpolation: what :meth:`to_complex` gives to ~1e-4 px, at a per-frame cost (NaN outside the
        view's field)."""
        uv = check_points(uv_rect, "uv_rect", 2)
        mu, mv = self.maps(view)
        h, w = mu.shape
        u = np.clip(uv[:, 0], 0, w - 1.000001)
        v = np.clip(uv[:, 1], 0, h - 1.000001)
        with np.errstate(invalid="ignore"):
            inside = (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
        u, v = np.where(inside, u, 0.0), np.where(inside, v, 0.0)
        u0, v0 = u.astype(int), v.astype(int)
        fu, fv = u - u0, v - v0
        out = np.empty((len(uv), 2))
        corners = [mu[v0, u0], mu[v0, u0 + 1], mu[v0 + 1, u0], mu[v0 + 1, u0 + 1]]
        for k, m in enumerate((mu, mv)):
            a, b, c, d = m[v0, u0], m[v0, u0 + 1], m[v0 + 1, u0], m[v0 + 1, u0 + 1]
            out[:, k] = (1 - fv) * ((1 - fu) * a + fu * b) + fv * ((1 - fu) * c + fu * d)
        inside &= np.min(corners, axis=0) >= 0                    # all four nodes inside the field
        out[~inside] = np.nan
        return out

    def maps(self, view: str) -> tuple[np.ndarray, np.ndarray]:
        """cv2.remap maps (map_u, map_v), float32 (H', W'): the complex-image pixel of each rectified pixel
        (-1 outside the view's field)."""
        view = _check_view(view)
        if view not in self._maps:
            self._maps[view] = _build_maps(self, view)
        return self._maps[view]

    def preload_maps(self, view: str, map_u: np.ndarray, map_v: np.ndarray) -> None:
        """Give :meth:`maps` of one view without computing them: (map_u, map_v) float32 (H', W') as
        :meth:`maps` returned them for this rectification's values (read back from a store)."""
        view = _check_view(view)
        w, h = self.size_px
        for name, m in (("map_u", map_u), ("map_v", map_v)):
            if not (isinstance(m, np.ndarray) and m.dtype == np.float32 and m.shape == (h, w)):
                raise ValueError(f"{name} must be a float32 array of shape ({h}, {w}), got "
                                 f"{getattr(m, 'dtype', type(m).__name__)} {getattr(m, 'shape', '')}")
        self._maps[view] = (map_u, map_v)

    def remap(self, image: np.ndarray, view: str, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
        """The complex image resampled on the rectified grid of one view (H', W'): that view's content with
        its epipolar curves as rows (the other view's content is warped along, not rectified)."""
        mu, mv = self.maps(view)
        return cv2.remap(np.asarray(image), mu, mv, interpolation, borderMode=cv2.BORDER_REPLICATE)

    def remap_fast(self, image: np.ndarray, view: str, window: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """:meth:`remap` (bilinear) through OpenCV's fixed-point maps: several times faster, with the
        sample positions rounded to 1/32 px (what cv2.remap does to float maps as well). ``window``
        (r0, r1, c0, c1): only rectified rows r0..r1-1 and columns c0..c1-1 (clipped to the grid; the
        result's pixel (0, 0) is rectified pixel (c0, r0) after clipping)."""
        view = _check_view(view)
        if view not in self._fixed:
            self._fixed[view] = cv2.convertMaps(*self.maps(view), cv2.CV_16SC2)
        m1, m2 = self._fixed[view]
        if window is not None:
            (r0, r1), (c0, c1) = _clip_span(window[:2], m1.shape[0]), _clip_span(window[2:], m1.shape[1])
            m1, m2 = m1[r0:r1, c0:c1], m2[r0:r1, c0:c1]
        return cv2.remap(np.asarray(image), m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def _clip_span(span, size: int) -> tuple[int, int]:
    """(start, stop) of a window clipped to 0..size, never empty."""
    start = min(max(0, int(span[0])), size - 1)
    return start, max(start + 1, min(size, int(span[1])))


def _check_view(view: str) -> str:
    if view not in VIEWS:
        raise ValueError(f"view must be 'left' or 'right', got {view!r}")
    return view


def _build_maps(rect: Rectification, view: str) -> tuple[np.ndarray, np.ndarray]:
    from scipy.interpolate import RectBivariateSpline  # here: a command that reads the maps from the cache
    w, h = rect.size_px                                  # need not load scipy.interpolate (0.3 s)
    gu = np.arange(0, w + _GRID_STEP_PX, _GRID_STEP_PX, dtype=float)
    gv = np.arange(0, h + _GRID_STEP_PX, _GRID_STEP_PX, dtype=float)
    uu, vv = np.meshgrid(gu, gv)
    uv = rect.to_complex(np.column_stack([uu.ravel(), vv.ravel()]), view).reshape(len(gv), len(gu), 2)
    cw, ch = rect.rig.camera.image_size_px
    inside = np.all(np.isfinite(uv), axis=2)
    # fill the nodes no ray reaches with their nearest reached node, so the spline stays smooth; the
    # pixels they cover are marked outside below
    filled = uv.copy()
    if not inside.all():
        from scipy.ndimage import distance_transform_edt
        _, (iv, iu) = distance_transform_edt(~inside, return_indices=True)
        filled = uv[iv, iu]
    pu, pv = np.arange(w, dtype=float), np.arange(h, dtype=float)
    out = []
    for k in range(2):
        spline = RectBivariateSpline(gv, gu, filled[..., k], kx=3, ky=3)
        out.append(spline(pv, pu))
    mu, mv = out
    reached = RectBivariateSpline(gv, gu, inside.astype(float), kx=1, ky=1)(pv, pu) > 0.999
    outside = ~reached | (mu < -0.5) | (mu > cw - 0.5) | (mv < -0.5) | (mv > ch - 0.5)
    mu[outside] = -1.0
    mv[outside] = -1.0
    return mu.astype(np.float32), mv.astype(np.float32)


def _left_centre(rig: Rig) -> np.ndarray:
    """The point nearest (least squares) to the left view's traced rays over the field, mm."""
    w, h = rig.camera.image_size_px
    uu, vv = np.meshgrid(np.linspace(0, w - 1, 17), np.linspace(0, h - 1, 13))
    r = trace_pixels(np.column_stack([uu.ravel(), vv.ravel()]), rig, "left")
    o, d = r.origins_mm[r.valid], r.dirs[r.valid]
    if len(o) < 3:
        return virtual_centre(rig, "left")
    P = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    return np.linalg.solve(P.sum(axis=0), np.einsum("nij,nj->i", P, o))


def _frame(c_left: np.ndarray, c_right: np.ndarray, rig: Rig) -> np.ndarray:
    """Rotation whose rows are x' (along C_r - C_l), y', z' (the views' mean optical axis, made normal
    to x')."""
    ex = c_right - c_left
    ex = ex / np.linalg.norm(ex)
    axis = direction_map(rig, "left") @ [0.0, 0.0, 1.0] + direction_map(rig, "right") @ [0.0, 0.0, 1.0]
    ez = axis - ex * (axis @ ex)
    ez /= np.linalg.norm(ez)
    return np.stack([ex, np.cross(ez, ex), ez])


def field_twins(rig: Rig, depths_mm, grid: tuple[int, int]) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each depth (Z of frame C, mm): the twin pixels (left (N, 2), right (N, 2)) of the points the left
    view's rays of a ``grid`` (columns, rows) of pixels over the image meet there, both inside the image
    (traced exactly: the plate, the mirrors as built, the lens)."""
    w, h = rig.camera.image_size_px
    uu, vv = np.meshgrid(np.linspace(0, w - 1, grid[0]), np.linspace(0, h - 1, grid[1]))
    left = np.column_stack([uu.ravel(), vv.ravel()])
    rays = trace_pixels(left, rig, "left")
    out = []
    for z in depths_mm:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (z - rays.origins_mm[:, 2]) / rays.dirs[:, 2]
        ok = rays.valid & (t > 0)
        right, seen = project_points(rays.origins_mm[ok] + t[ok, None] * rays.dirs[ok], rig, "right")
        seen &= (right[:, 0] >= 0) & (right[:, 0] <= w - 1) & (right[:, 1] >= 0) & (right[:, 1] <= h - 1)
        out.append((left[ok][seen], right[seen]))
    return out


def _samples(rig: Rig, near_mm: float, far_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Twin pixels (left (N, 2), right (N, 2)) of points on a grid of left pixels x depths (uniform in
    1/Z over the working range), both inside the image: the fit's data."""
    twins = field_twins(rig, 1.0 / np.linspace(1.0 / far_mm, 1.0 / near_mm, 7), (21, 15))
    return np.concatenate([lt for lt, _ in twins]), np.concatenate([rt for _, rt in twins])


def remembered(rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> Rectification | None:
    """The rectification :func:`rectify` keeps in memory for this rig and range, or None (nothing is fitted)."""
    key = (rig, float(near_mm), float(far_mm))
    with _MEMORY_LOCK:
        rect = _MEMORY.get(key)
        if rect is not None:
            _MEMORY.move_to_end(key)
        return rect


def remember(rect: Rectification) -> Rectification:
    """Make ``rect`` what :func:`rectify` returns for its rig and range from now on in this process (a
    rectification read back from a store, with the same values); when one is already kept, that one stays
    and is returned, so every caller shares one object (and its maps)."""
    key = (rect.rig, rect.near_mm, rect.far_mm)
    with _MEMORY_LOCK:
        kept = _MEMORY.setdefault(key, rect)
        _MEMORY.move_to_end(key)
        while len(_MEMORY) > _KEPT:
            _MEMORY.popitem(last=False)
        return kept


def forget() -> None:
    """Empty the memory of :func:`rectify` (the next call fits again)."""
    with _MEMORY_LOCK:
        _MEMORY.clear()


def rectify(rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> Rectification:
    """The dual rectification of a rig over the working range near..far (mm), kept in memory per rig and
    range (the last few used; :func:`remembered`).

    Fitted: the left centre's height and depth (its x only moves the disparity's origin) and z_ref, so
    that the two views' rectified rows agree on twin pixels of points spread over the field and over the
    range (least squares; the right view is exact by construction). K' keeps the camera's focal length in
    px; the rectified image is as large as needed to hold both views' whole field.

    Examples
    --------
    >>> from psvs.io.params import load_rig
    >>> rect = rectify(load_rig("misaligned"))
    >>> bool(rect.residual_px < 0.05), round(rect.baseline_mm, 1)
    (True, 100.1)
    """
    if not 0 < near_mm < far_mm:
        raise ValueError(f"working range must satisfy 0 < near < far, got near={near_mm!r}, far={far_mm!r}")
    rect = remembered(rig, near_mm, far_mm)
    return rect if rect is not None else remember(_fit(rig, float(near_mm), float(far_mm)))


def _fit(rig: Rig, near_mm: float, far_mm: float) -> Rectification:
    """:func:`rectify`'s work, without the memory."""
    cam = rig.camera
    fx, fy = cam.focal_length_mm / cam.pixel_pitch_mm[0], cam.focal_length_mm / cam.pixel_pitch_mm[1]
    c_right = virtual_centre(rig, "right")
    c0 = _left_centre(rig)
    left_px, right_px = _samples(rig, near_mm, far_mm)
    if len(left_px) < 20:
        raise ValueError(f"the rig's views share too little of the field over {near_mm:g}-{far_mm:g} mm "
                         "to rectify (fewer than 20 twin samples)")
    rays_l = trace_pixels(left_px, rig, "left")
    rays_r = trace_pixels(right_px, rig, "right")

    def rows(p):
        c_left = c0 + [0.0, p[0], p[1]]
        R = _frame(c_left, c_right, rig)
        out = []
        for r in (rays_l, rays_r):
            t = (p[2] - r.origins_mm[:, 2]) / r.dirs[:, 2]
            q = (r.origins_mm + t[:, None] * r.dirs - c_right) @ R.T   # rows are the same from C_l or C_r
            out.append(fy * q[:, 1] / q[:, 2])
        return out[0] - out[1]

    z0 = 2.0 / (1.0 / near_mm + 1.0 / far_mm)
    from scipy.optimize import least_squares  # here: only a fit (not a cached rig) needs it
    sol = least_squares(rows, [0.0, 0.0, z0], x_scale=[0.1, 0.1, 100.0])
    c_left = c0 + [0.0, sol.x[0], sol.x[1]]
    R = _frame(c_left, c_right, rig)
    K = np.array([[fx, 0.0, cam.principal_point_px[0]], [0.0, fy, cam.principal_point_px[1]], [0.0, 0.0, 1.0]])
    rect = Rectification(rig, R, K, {"left": c_left, "right": c_right}, float(sol.x[2]), cam.image_size_px,
                         float(np.max(np.abs(rows(sol.x)))), float(near_mm), float(far_mm))
    return _grow_to_field(rect)


def _grow_to_field(rect: Rectification) -> Rectification:
    """The same rectification with K's principal point and the image size chosen so that every pixel of
    the camera's border lands inside the rectified image, in both views."""
    w, h = rect.rig.camera.image_size_px
    t = np.linspace(0.0, 1.0, 65)
    border = np.concatenate([np.column_stack([t * (w - 1), np.zeros_like(t)]),
                             np.column_stack([t * (w - 1), np.full_like(t, h - 1)]),
                             np.column_stack([np.zeros_like(t), t * (h - 1)]),
                             np.column_stack([np.full_like(t, w - 1), t * (h - 1)])])
    pts = np.concatenate([rect.to_rectified(border, v) for v in VIEWS])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    lo = np.maximum(np.floor(pts.min(axis=0)), [-(_MAX_GROWTH - 1) * w / 2, -(_MAX_GROWTH - 1) * h / 2])
    hi = np.minimum(np.ceil(pts.max(axis=0)), [w - 1 + (_MAX_GROWTH - 1) * w / 2, h - 1 + (_MAX_GROWTH - 1) * h / 2])
    K = rect.camera_matrix.copy()
    K[0, 2] -= lo[0]
    K[1, 2] -= lo[1]
    size = (int(hi[0] - lo[0]) + 1, int(hi[1] - lo[1]) + 1)
    return Rectification(rect.rig, rect.rotation, K, rect.centres_mm, rect.z_ref_mm, size, rect.residual_px,
                         rect.near_mm, rect.far_mm)
