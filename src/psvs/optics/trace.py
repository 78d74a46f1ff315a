"""Vectorised chief-ray tracing through the rig, pixel <-> camera-ray conversions.

A pixel's chief ray leaves O along (x, y, f) with x = (u - cx) pitch_x, y = (v - cy) pitch_y, then
follows its view's path (:func:`psvs.optics.mirrors.path`): two mirrors for the right view; the M1
plate (Snell refraction at both faces) and two mirrors for the left view. A ray that misses a finite
mirror or plate face is vignetted: its row stays computed but ``valid`` is False; so is one that another
finite mirror, or the plate's box, blocks on its way (:mod:`psvs.optics.solids`).
"""
from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from psvs._threads import pool_size
from psvs._validate import check_points
from psvs.optics.kernels import PASS, REFLECT, REFRACT, trace_path, undistort_fixed_point, unit_camera_dirs
from psvs.optics.mirrors import mirror_planes, path
from psvs.optics.rig import Camera, Rig
from psvs.optics.solids import LABEL, SCENE_DEPTH_MM, SOLIDS, bounding_box, finite_solids, occluded
from psvs.optics.surfaces import EXTENT_TOL_MM, intersect, reflect, refract

#: Rays a thread of :func:`trace_camera_rays` traces at a time (fewer go on one thread).
THREAD_CHUNK = 1 << 16
#: The fewest rays worth a thread of their own (a pool's start costs about what 100 rays do).
MIN_SPLIT = 4096


class Rays(NamedTuple):
    """Rays leaving the rig toward the scene.

    origins_mm : (N, 3) point on the ray (its hit on the last mirror), mm.
    dirs : (N, 3) unit direction toward the scene.
    valid : (N,) bool, False where the ray was vignetted or undefined (NaN input).
    """

    origins_mm: np.ndarray
    dirs: np.ndarray
    valid: np.ndarray


def sensor_from_pixels(uv_px: np.ndarray, camera: Camera) -> np.ndarray:
    """Sensor coordinates (x, y), shape (N, 2), mm, of pixels (u, v), shape (N, 2), px."""
    return (uv_px - np.asarray(camera.principal_point_px)) * np.asarray(camera.pixel_pitch_mm)


def pixels_from_sensor(xy_mm: np.ndarray, camera: Camera) -> np.ndarray:
    """Pixels (u, v), shape (N, 2), px, of sensor coordinates (x, y), shape (N, 2), mm."""
    return xy_mm / np.asarray(camera.pixel_pitch_mm) + np.asarray(camera.principal_point_px)


def _coefficients(dist) -> tuple[float, float, float, float, float]:
    """(k1, k2, p1, p2, k3) from OpenCV's 2-, 4- or 5-vector."""
    c = tuple(float(x) for x in dist)
    if len(c) not in (2, 4, 5):
        raise ValueError(f"distortion must hold 2, 4 or 5 coefficients (k1, k2[, p1, p2[, k3]]), got {len(c)}")
    return (c + (0.0, 0.0, 0.0))[:5]


def distort(xn: np.ndarray, dist) -> np.ndarray:
    """OpenCV's lens distortion of normalised image coordinates (N, 2) (see :class:`Camera`).

    ``dist`` is (k1, k2, p1, p2, k3), or its first 2 or 4 terms. Returns distorted coordinates (N, 2).
    """
    k1, k2, p1, p2, k3 = _coefficients(dist)
    x, y = xn[:, 0], xn[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    out = np.empty_like(xn)
    out[:, 0] = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    out[:, 1] = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return out


def undistort(xd: np.ndarray, dist, iterations: int = 50, tol: float = 1e-15) -> np.ndarray:
    """Inverse of :func:`distort`: fixed-point iteration x <- (x_d - tangential(x)) / radial(x), as
    OpenCV's ``undistortPoints``, run to convergence (contracts fast for the moderate terms of real
    lenses: |k1| r^2 ~ 0.03 at the corners of a 1/2" sensor behind an 11 mm lens), each point until it moves
    by ``tol`` or less (:func:`psvs.optics.kernels.undistort_fixed_point`)."""
    k1, k2, p1, p2, k3 = _coefficients(dist)
    xd = np.ascontiguousarray(xd, dtype=np.float64)
    return undistort_fixed_point(xd, k1, k2, p1, p2, k3, int(iterations), float(tol))


def ideal_sensor_from_pixels(uv_px: np.ndarray, camera: Camera) -> np.ndarray:
    """Distortion-free sensor coordinates (N, 2), mm, of pixels (N, 2): what eqs. (9)-(17) call x, y."""
    xy = sensor_from_pixels(uv_px, camera)
    if not camera.distorted:
        return xy
    f = camera.focal_length_mm
    return undistort(xy / f, camera.distortion) * f


#: Few-pixel calls of :func:`camera_dirs` remembered (read-only results): the mirror design's searches trace
#: the same few hundred field pixels of one camera through up to a thousand trial layouts, and undoing a
#: strong lens's distortion is most of a layout's cost.
_DIRS_CACHE: OrderedDict = OrderedDict()
_DIRS_LOCK = threading.Lock()
_DIRS_CACHE_SIZE, _DIRS_CACHE_MAX_PX = 16, 1024


def camera_dirs(uv_px: np.ndarray, camera: Camera) -> np.ndarray:
    """Unit directions (N, 3) in frame C of the real camera's rays through pixels (N, 2) px (read-only
    when N is small: such calls are remembered)."""
    uv = np.ascontiguousarray(uv_px, dtype=np.float64)
    key = (camera, uv.shape, uv.tobytes()) if len(uv) <= _DIRS_CACHE_MAX_PX else None
    if key is not None:
        with _DIRS_LOCK:   # the web app traces from several threads
            d = _DIRS_CACHE.get(key)
            if d is not None:
                _DIRS_CACHE.move_to_end(key)
                return d
    cam = np.array([*camera.principal_point_px, *camera.pixel_pitch_mm, camera.focal_length_mm,
                    float(camera.distorted)])
    dist = np.array(_coefficients(camera.distortion) if camera.distorted else (0.0,) * 5)
    d = np.empty((len(uv), 3))
    in_parts(len(uv), lambda a, b: unit_camera_dirs(uv[a:b], cam, dist, 50, 1e-15, d[a:b]))
    if key is not None:
        d.setflags(write=False)
        with _DIRS_LOCK:
            _DIRS_CACHE[key] = d
            if len(_DIRS_CACHE) > _DIRS_CACHE_SIZE:
                _DIRS_CACHE.popitem(last=False)
    return d


def pixels_from_camera_dirs(dirs: np.ndarray, camera: Camera) -> np.ndarray:
    """Pixels (N, 2) px hit by camera rays of directions (N, 3) (through the lens's distortion);
    NaN where d_z <= 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(dirs[:, 2] > 0, dirs[:, 2], np.nan)
        xn = dirs[:, :2] / z[:, None]
    if camera.distorted:
        xn = distort(xn, camera.distortion)
    return pixels_from_sensor(camera.focal_length_mm * xn, camera)


def trace_rays(origins_mm: np.ndarray, dirs: np.ndarray, steps: list[tuple], hits: list | None = None) -> Rays:
    """Follow rays (N, 3) through a list of surface steps (see :func:`psvs.optics.mirrors.path`).

    A finite surface (with an extent) is physical: the ray must meet it ahead of the previous surface
    and inside its rectangle, or it is vignetted. An unbounded surface is the paper's ideal plane: the
    reflected or refracted *line* is the same on either side of the hit, so only a parallel ray fails.
    When ``hits`` is a list, ``(plane, points_mm (N, 3), ahead (N,))`` is appended for every surface met.
    """
    o, d = origins_mm, dirs
    valid = np.all(np.isfinite(d), axis=1) & np.all(np.isfinite(o), axis=1)
    for step in steps:
        kind, plane = step[0], step[1]
        t, o, ahead = intersect(o, d, plane)
        valid &= np.isfinite(t)
        if plane.extent is not None:
            valid &= ahead & plane.contains(o)
        if hits is not None:
            hits.append((plane, o, ahead))
        if kind == "reflect":
            d = reflect(d, plane.normal)
        elif kind == "refract":
            d, ok = refract(d, plane.normal, step[2])
            valid &= ok
    return Rays(o, d, valid)


@functools.lru_cache(maxsize=64)
def _packed_path(rig: Rig, view: str):
    """One view's path (:func:`psvs.optics.mirrors.path`) and the rig's solids as
    :func:`psvs.optics.kernels.trace_path` reads them (read-only arrays, computed once per rig and view)."""
    kinds = {"reflect": REFLECT, "refract": REFRACT, "pass": PASS}
    steps = path(rig, view)
    geo = np.full((len(steps), 16), np.nan)
    eta = np.zeros(len(steps))
    for k, step in enumerate(steps):
        plane = step[1]
        geo[k, :12] = np.concatenate([plane.point, plane.normal, plane.s_axis, plane.t_axis])
        if plane.extent is not None:
            geo[k, 12:] = (*plane.extent.along_mm, *plane.extent.height_mm)
        if step[0] == "refract":
            eta[k] = step[2]
    kind = np.array([kinds[s[0]] for s in steps], dtype=np.int64)
    label = np.array([SOLIDS.index(LABEL[s[1].name]) for s in steps], dtype=np.int64)
    planes, finite = mirror_planes(rig), finite_solids(rig)
    solids = np.zeros((len(SOLIDS), 23))
    on = np.array([s in finite for s in SOLIDS])
    for m, solid in enumerate(SOLIDS):
        if on[m]:
            plane = planes["m1" if solid == "M1 plate" else solid.lower()]
            thick = rig.mirrors.plate_thickness_mm if solid == "M1 plate" else 0.0
            solids[m] = np.concatenate([plane.point, plane.normal, plane.s_axis, plane.t_axis,
                                        (*plane.extent.along_mm, *plane.extent.height_mm, thick),
                                        *bounding_box(plane, thick)])
    out = (geo, kind, eta, label, solids, on)
    for a in out:
        a.setflags(write=False)
    return out


def trace_camera_rays(dirs: np.ndarray, rig: Rig, view: str, occlusion: bool = True) -> Rays:
    """Rays from the camera's centre O along camera directions ``dirs`` (N, 3) through one view: what
    :func:`trace_rays` (from O) then, with ``occlusion``, :func:`psvs.optics.solids.occluded` give, in one
    compiled pass a ray (:func:`psvs.optics.kernels.trace_path`; large inputs on the threads of
    :func:`psvs._threads.pool_size`), without keeping the path's points: the tracer of every pixel and
    projection. tests/optics/test_trace_kernel.py holds it to the NumPy form on drawn rigs and rays."""
    d = np.ascontiguousarray(dirs, dtype=np.float64)
    geo, kind, eta, label, solids, on = _packed_path(rig, view)
    occlusion = bool(occlusion and on.any())
    n = len(d)
    out = Rays(np.empty((n, 3)), np.empty((n, 3)), np.empty(n, dtype=bool))
    in_parts(n, lambda a, b: trace_path(d[a:b], geo, kind, eta, label, solids, on, SCENE_DEPTH_MM, EXTENT_TOL_MM,
                                        out.origins_mm[a:b], out.dirs[a:b], out.valid[a:b], occlusion))
    return out


def in_parts(n: int, work) -> None:
    """``work(a, b)`` over [0, n) in parts of :data:`THREAD_CHUNK`, on the threads of
    :func:`psvs._threads.pool_size` when there are several parts (the kernels release the GIL); fewer items
    than a part a thread, down to :data:`MIN_SPLIT` a thread, are shared out evenly (a depth map's 15 000
    pixels beyond its table: 27 ms on one thread)."""
    cores = pool_size()
    chunk = THREAD_CHUNK if n >= cores * THREAD_CHUNK else max(MIN_SPLIT, -(-n // cores))
    starts = range(0, n, chunk)
    threads = pool_size(len(starts)) if len(starts) > 1 else 1     # one part (or none): no pool
    if threads > 1:
        with ThreadPoolExecutor(threads) as ex:
            list(ex.map(lambda a: work(a, min(n, a + chunk)), starts))
    else:
        for a in starts:
            work(a, min(n, a + chunk))


def trace_pixels(uv_px, rig: Rig, view: str, hits: list | None = None) -> Rays:
    """Back-project pixels of one view to the rays they see in the scene.

    Parameters
    ----------
    uv_px : array_like, shape (N, 2)
        Pixel positions (u, v) in the complex image, px.
    rig : Rig
    view : {'left', 'right'}

    Returns
    -------
    Rays
        Origins (N, 3) mm on the view's last mirror, unit directions (N, 3), validity (N,): False where
        the ray misses one of its own finite mirrors, or where another finite mirror or the plate's box
        blocks it on its way (:func:`psvs.optics.solids.occluded`, the test ``psvs design`` reports).

    Examples
    --------
    >>> from psvs import default_rig
    >>> rays = trace_pixels([[319.5, 239.5]], default_rig(), "right")
    >>> rays.origins_mm.round(6), rays.dirs.round(6), rays.valid
    (array([[50., 0., 22.]]), array([[0., 0., 1.]]), array([ True]))
    """
    uv = check_points(uv_px, "uv_px", 2)
    dirs = camera_dirs(uv, rig.camera)
    if hits is None:
        return trace_camera_rays(dirs, rig, view)
    rays = trace_rays(np.zeros_like(dirs), dirs, path(rig, view), hits)
    if not finite_solids(rig):
        return rays
    return rays._replace(valid=rays.valid & ~occluded(rig, hits, rays.origins_mm, rays.dirs))


def lit_pairs(left_px: np.ndarray, right_px: np.ndarray, rig: Rig) -> np.ndarray:
    """bool (N,): the pairs (complex-image px, (N, 2) each) whose left pixel the left view's light reaches and
    whose right pixel the right view's does, through the rig's glass as sized in it
    (:func:`trace_pixels`): where the glass vignettes a view, what the image shows there is
    not that view (its edges are the glass's or the other view's). A rig without mirror sizes (the paper's ideal
    planes) blocks nothing."""
    if not finite_solids(rig) or not len(left_px):
        return np.ones(len(left_px), dtype=bool)
    return trace_pixels(left_px, rig, "left").valid & trace_pixels(right_px, rig, "right").valid
