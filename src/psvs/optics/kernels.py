"""The ray tracer's per-ray loops as Numba kernels (compiled once per machine, kept in ``__pycache__``): undoing
the lens's distortion, the bounding-box pre-test of the blocking solids, and a ray's whole path through one
view (its surfaces, then the solids that block it). Each is one pass over the rays in place of NumPy's dozen
temporary arrays; :mod:`psvs.optics.trace` and :mod:`psvs.optics.solids` call them and keep the formulas'
documentation (their NumPy forms remain for the reports that name which surface or solid stops a ray, and
tests/optics/test_trace_kernel.py holds the kernel to them)."""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True, error_model="numpy")   # a zero radial factor gives inf, as NumPy did
def _undistort_one(xd0, yd0, dist, iterations, tol):  # pragma: no cover - compiled
    """One point of :func:`undistort_fixed_point` (``dist`` (5,) k1, k2, p1, p2, k3): (x, y) normalised."""
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    x, y = xd0, yd0
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        nx = (xd0 - 2.0 * p1 * x * y - p2 * (r2 + 2.0 * x * x)) / radial
        ny = (yd0 - p1 * (r2 + 2.0 * y * y) - 2.0 * p2 * x * y) / radial
        moved = abs(nx - x) > tol or abs(ny - y) > tol
        x, y = nx, ny
        if not moved:
            break
    return x, y


@nb.njit(cache=True, nogil=True, error_model="numpy")
def undistort_fixed_point(xd, k1, k2, p1, p2, k3, iterations, tol):  # pragma: no cover - compiled
    """Normalised undistorted points (N, 2) of distorted ones ``xd`` (N, 2): per point, the fixed-point
    iteration x <- (x_d - tangential(x)) / radial(x) until it moves by ``tol`` or less (at most
    ``iterations``); a NaN point stays NaN."""
    out = np.empty_like(xd)
    dist = np.array((k1, k2, p1, p2, k3))
    for i in range(xd.shape[0]):
        out[i, 0], out[i, 1] = _undistort_one(xd[i, 0], xd[i, 1], dist, iterations, tol)
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def unit_camera_dirs(uv, cam, dist, iterations, tol, out):  # pragma: no cover - compiled
    """Unit camera-ray directions into ``out`` (N, 3) of pixels ``uv`` (N, 2): ``cam`` (6,) is (cx, cy,
    pitch_x, pitch_y, f, distorted), ``dist`` (5,) (k1, k2, p1, p2, k3); the sensor point (u - cx) pitch_x,
    (v - cy) pitch_y, its distortion undone (:func:`undistort_fixed_point` on x / f), then (x, y, f)
    normalised: :func:`psvs.optics.trace.camera_dirs` in one pass."""
    f = cam[4]
    for i in range(uv.shape[0]):
        x = (uv[i, 0] - cam[0]) * cam[2]
        y = (uv[i, 1] - cam[1]) * cam[3]
        if cam[5] != 0:
            x, y = _undistort_one(x / f, y / f, dist, iterations, tol)
            x, y = x * f, y * f
        norm = np.sqrt(x * x + y * y + f * f)
        out[i, 0], out[i, 1], out[i, 2] = x / norm, y / norm, f / norm


@nb.njit(cache=True, nogil=True)
def _box_meets(p0s, i0, p1s, i1, boxes, b, at):  # pragma: no cover - compiled
    """Whether the axis-aligned bounding box of the segment p0s[i0] -> p1s[i1] (rows (3,)) meets the box whose
    lo (3) and hi (3) are boxes[b, at:at + 6] (a NaN coordinate meets nothing). Element reads, no row views: a view
    takes and drops a reference on its array, an atomic operation (the occlusion test took 4-14 times a ray's
    path so)."""
    for k in range(3):
        a, c = p0s[i0, k], p1s[i1, k]
        if np.isnan(a) or np.isnan(c) or max(a, c) < boxes[b, at + k] or min(a, c) > boxes[b, at + 3 + k]:
            return False
    return True


@nb.njit(cache=True, nogil=True)
def boxes_meet(p0s, p1s, lo, hi):  # pragma: no cover - compiled
    """Mask (N,) of segments p0s -> p1s (N, 3) whose axis-aligned bounding box meets the box [lo, hi] (3,)
    (a NaN coordinate meets nothing)."""
    box = np.empty((1, 6))
    box[0, :3], box[0, 3:] = lo, hi
    out = np.zeros(p0s.shape[0], dtype=np.bool_)
    for i in range(p0s.shape[0]):
        out[i] = _box_meets(p0s, i, p1s, i, box, 0, 0)
    return out


#: :func:`trace_path`'s step kinds (``psvs.optics.mirrors.path``'s words) and its path labels besides the solids
REFLECT, REFRACT, PASS = 0, 1, 2
CAMERA, SCENE = -1, -2


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _segment_blocked(pts, j, solids, m, plate):  # pragma: no cover - compiled
    """Whether the segment pts[j] -> pts[j + 1] (rows of ``pts`` (P, 3)) crosses one solid ``solids[m]`` (23,):
    its plane's point, normal, s and t axes (12), its rectangle s0, s1, t0, t1 (4), the plate's thickness (1)
    and its bounding box lo, hi (6); ``plate``: the box of the M1 plate (slab method), else the rectangle
    (crossed strictly inside). :func:`psvs.optics.solids.segments_hit`, one segment, read element by element
    (:func:`_box_meets`)."""
    if not _box_meets(pts, j, pts, j + 1, solids, m, 17):     # the bounding-box pre-test
        return False
    off = solids[m, 0] * solids[m, 3] + solids[m, 1] * solids[m, 4] + solids[m, 2] * solids[m, 5]
    d0 = pts[j, 0] * solids[m, 3] + pts[j, 1] * solids[m, 4] + pts[j, 2] * solids[m, 5] - off
    d1 = pts[j + 1, 0] * solids[m, 3] + pts[j + 1, 1] * solids[m, 4] + pts[j + 1, 2] * solids[m, 5] - off
    s0, s1, t0, t1, thick = solids[m, 12], solids[m, 13], solids[m, 14], solids[m, 15], solids[m, 16]
    if not plate:
        if not d0 * d1 < 0:
            return False
        f = d0 / (d0 - d1)
        s = t = 0.0
        for k in range(3):
            r = pts[j, k] + f * (pts[j + 1, k] - pts[j, k]) - solids[m, k]
            s += r * solids[m, 6 + k]
            t += r * solids[m, 9 + k]
        return s0 < s < s1 and t0 < t < t1
    za, zb = -d0, -d1    # depth into the glass
    if (za <= 0 and zb <= 0) or (za >= thick and zb >= thick) or not (np.isfinite(za) and np.isfinite(zb)):
        return False
    sa = ta = sb = tb = 0.0
    for k in range(3):
        sa += (pts[j, k] - solids[m, k]) * solids[m, 6 + k]
        ta += (pts[j, k] - solids[m, k]) * solids[m, 9 + k]
        sb += (pts[j + 1, k] - solids[m, k]) * solids[m, 6 + k]
        tb += (pts[j + 1, k] - solids[m, k]) * solids[m, 9 + k]
    enter, leave = -np.inf, np.inf
    for k in range(3):    # the slab method on the box's three axes: s, t and the depth into the glass
        if k == 0:
            a, b, lo, hi = sa, sb, s0, s1
        elif k == 1:
            a, b, lo, hi = ta, tb, t0, t1
        else:
            a, b, lo, hi = za, zb, 0.0, thick
        d = b - a
        if d != 0:
            near, far = (lo - a) / d, (hi - a) / d
            if near > far:
                near, far = far, near
            if not np.isnan(near):
                enter = max(enter, near)
            if not np.isnan(far):
                leave = min(leave, far)
        elif a <= lo or a >= hi:
            return False
    return enter < leave and leave > 1e-9 and enter < 1 - 1e-9


@nb.njit(cache=True, nogil=True, error_model="numpy")
def trace_path(dirs, steps, kind, eta, label, solids, on, scene_depth_mm, tol_mm,  # noqa: PLR0913
               origins_out, dirs_out, valid_out, occlusion):  # pragma: no cover - compiled
    """Rays from the camera's centre O along ``dirs`` (N, 3) through one view's surfaces, in place into
    ``origins_out``, ``dirs_out`` (N, 3) and ``valid_out`` (N,): per ray, :func:`psvs.optics.trace.trace_rays`
    (``steps`` (S, 16): each plane's point, normal, s and t axes and rectangle, NaN bounds for an unbounded
    plane; ``kind`` (S,) of :data:`REFLECT`, :data:`REFRACT`, :data:`PASS`; ``eta`` (S,) n_before / n_after;
    ``label`` (S,) the solid each surface is part of), then with ``occlusion``
    :func:`psvs.optics.solids.occluded` (``solids`` (4, 23) as :func:`_segment_blocked` reads them, ``on`` (4,)
    the finite ones; the path's polyline ends ``scene_depth_mm`` beyond the last mirror)."""
    n_steps = steps.shape[0]
    pts = np.empty((n_steps + 2, 3))
    o = np.empty(3)
    d = np.empty(3)
    for i in range(dirs.shape[0]):
        ok = True
        for k in range(3):
            o[k] = 0.0
            d[k] = dirs[i, k]
            pts[0, k] = 0.0
            ok = ok and np.isfinite(d[k])
        for s in range(n_steps):     # the plane's values read element by element: a row view costs an atomic
            nx, ny, nz = steps[s, 3], steps[s, 4], steps[s, 5]     # reference count (2x the path's time)
            denom = d[0] * nx + d[1] * ny + d[2] * nz
            t = ((steps[s, 0] * nx + steps[s, 1] * ny + steps[s, 2] * nz) - (o[0] * nx + o[1] * ny + o[2] * nz)) / denom
            if abs(denom) <= 1e-15:
                t = np.nan
            for k in range(3):
                o[k] += t * d[k]
                pts[s + 1, k] = o[k]
            if not np.isfinite(t):
                ok = False
            if not np.isnan(steps[s, 12]):   # a finite surface: met ahead and inside its rectangle
                ls = lt = 0.0
                for k in range(3):
                    ls += (o[k] - steps[s, k]) * steps[s, 6 + k]
                    lt += (o[k] - steps[s, k]) * steps[s, 9 + k]
                inside = ((steps[s, 12] - tol_mm <= ls <= steps[s, 13] + tol_mm)
                          and (steps[s, 14] - tol_mm <= lt <= steps[s, 15] + tol_mm))
                if not (t > 0 and inside):
                    ok = False
            dn = d[0] * nx + d[1] * ny + d[2] * nz
            if kind[s] == 0:
                for k in range(3):
                    d[k] -= 2.0 * dn * steps[s, 3 + k]
            elif kind[s] == 1:
                side = -1.0 if dn > 0 else (1.0 if dn < 0 else 0.0)
                cos_i = abs(dn)
                sin2_t = eta[s] * eta[s] * (1.0 - cos_i * cos_i)
                if sin2_t <= 1.0:
                    cos_t = np.sqrt(max(1.0 - sin2_t, 0.0))
                    for k in range(3):
                        d[k] = eta[s] * d[k] + (eta[s] * cos_i - cos_t) * side * steps[s, 3 + k]
                else:
                    ok = False
                    for k in range(3):
                        d[k] = np.nan
        for k in range(3):
            origins_out[i, k] = o[k]
            dirs_out[i, k] = d[k]
            pts[n_steps + 1, k] = o[k] + scene_depth_mm * d[k]
        if ok and occlusion:
            for j in range(n_steps + 1):
                start = CAMERA if j == 0 else label[j - 1]
                end = SCENE if j == n_steps else label[j]
                if start == end == 0:
                    continue   # inside the glass
                for m in range(4):
                    if on[m] and m != start and m != end and _segment_blocked(pts, j, solids, m, m == 0
                                                                               and solids[m, 16] > 0):
                        ok = False
                        break
                if not ok:
                    break
        valid_out[i] = ok
