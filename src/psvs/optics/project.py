"""Projection of 3-D points into each view of the complex image, through the exact optics.

The right view is a pinhole at O2 (pure reflections). The left view is not central: the M1 plate shifts
each transmitted ray sideways by an amount that depends on its direction, so the pixel seeing a point is
found by a fixed-point iteration: trace the current camera ray, aim the camera ray at the point from where
the traced ray leaves the rig, repeat. The plate shift changes by ~1e-3 mm per mm of ray displacement, so
the iteration contracts by roughly (shift derivative) / (distance to the point) per step: a handful of
iterations reach 1e-10 px. The iteration runs on camera rays, not pixels: a pixel needs the lens's
distortion inverted (an iteration of its own) before it can be traced, a ray only needs it applied
(closed form) to give its pixel.
"""
from __future__ import annotations

import numpy as np

from psvs._validate import check_points
from psvs.optics.mirrors import direction_map, virtual_centre
from psvs.optics.rig import Rig
from psvs.optics.trace import pixels_from_camera_dirs, trace_camera_rays


def project_points(points_mm, rig: Rig, view: str, *, tol_px: float = 1e-10, max_iter: int = 60):
    """Pixels where scene points appear in one view of the complex image (:func:`project_from` without a start).

    Parameters
    ----------
    points_mm : array_like, shape (N, 3)
        Points in frame C, mm.
    rig : Rig
    view : {'left', 'right'}
    tol_px : float
        Convergence threshold on the pixel update, px.
    max_iter : int

    Returns
    -------
    uv_px : ndarray, shape (N, 2)
        (u, v) in px; may lie outside the image (check with :func:`in_image`). NaN where invalid.
    valid : ndarray of bool, shape (N,)
        False where the chief ray is vignetted by a finite mirror or blocked by another one (or the
        plate's box), the point is behind the rig, the input is NaN, or the iteration did not converge.

    Examples
    --------
    >>> from psvs import default_rig
    >>> rig = default_rig().replace(plate_thickness_mm=0.0)
    >>> uv, ok = project_points([[50.0, 0.0, 450.0]], rig, "right")   # on O2's axis: image centre
    >>> uv.round(9), ok
    (array([[319.5, 239.5]]), array([ True]))
    """
    uv, valid, _ = project_from(points_mm, rig, view, None, tol_px=tol_px, max_iter=max_iter)
    return uv, valid


def project_from(points_mm, rig: Rig, view: str, start_dirs=None, *, tol_px: float = 1e-10, max_iter: int = 60):
    """:func:`project_points`, the iteration started from camera rays ``start_dirs`` (N, 3) (the rays a nearby
    rig or nearby points converged to: a numerical derivative's, which then takes 2-4 of the left view's
    6 iterations; None, or NaN rows: aimed from the view's virtual centre). Returns (uv_px (N, 2), valid (N,),
    the converged camera rays (N, 3), NaN where the input is)."""
    pts = check_points(points_mm, "points_mm", 3)
    cam = rig.camera
    R = direction_map(rig, view)
    centre = virtual_centre(rig, view)
    finite = np.all(np.isfinite(pts), axis=1)

    def aim(origins):
        d = pts - origins
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return d @ R                     # the camera ray: d_cam = R^T d_out, rows: d @ R

    def near_centre(rays):
        # Aim from the point of the traced ray nearest the virtual centre: there a change of direction
        # moves the ray least, so the update error is only the plate shift's variation (fast contraction).
        o, d = rays.origins_mm, rays.dirs
        return o + np.einsum("ij,ij->i", centre - o, d)[:, None] * d

    dirs = aim(centre[None, :])
    if start_dirs is not None:
        start = np.asarray(start_dirs, dtype=float).reshape(dirs.shape)
        usable = np.all(np.isfinite(start), axis=1)
        dirs[usable] = start[usable]
    uv = pixels_from_camera_dirs(dirs, cam)
    converged = np.zeros(len(pts), dtype=bool)
    for _ in range(max_iter):
        dirs = aim(near_centre(trace_camera_rays(dirs, rig, view, occlusion=False)))
        new = pixels_from_camera_dirs(dirs, cam)
        step = np.max(np.abs(new - uv), axis=1)
        uv = new
        converged = step <= tol_px
        if np.all(converged | ~np.isfinite(step)):
            break
    rays = trace_camera_rays(dirs, rig, view)   # invalid also where another mirror or the plate's box is in the way
    ahead = np.einsum("ij,ij->i", pts - rays.origins_mm, rays.dirs) > 0
    valid = finite & converged & rays.valid & ahead
    uv[~valid] = np.nan
    return uv, valid, dirs


def in_image(uv_px, rig: Rig) -> np.ndarray:
    """Mask (N,) of pixel positions (N, 2) inside the image (pixel centres 0..W-1, 0..H-1, +-0.5 px)."""
    uv = check_points(uv_px, "uv_px", 2)
    w, h = rig.camera.image_size_px
    with np.errstate(invalid="ignore"):
        return (uv[:, 0] >= -0.5) & (uv[:, 0] <= w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] <= h - 0.5)


def epipolar_curves_px(origins_mm, directions, z_mm, rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Left-view rays' epipolar curves in the right view: the right-view pixels (n, S, 2) of each ray's
    points at the depths ``z_mm`` (S,) mm, and which of them the right view sees (n, S) bool (``origins_mm``
    (n, 3) mm and unit ``directions`` (n, 3) from :func:`psvs.optics.trace.trace_pixels`; a point behind
    its ray's origin is not seen)."""
    o, d = np.atleast_2d(np.asarray(origins_mm, float)), np.atleast_2d(np.asarray(directions, float))
    z = np.asarray(z_mm, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z[None, :] - o[:, 2:3]) / d[:, 2:3]
    pts = o[:, None, :] + t[..., None] * d[:, None, :]
    uv, ok = project_points(pts.reshape(-1, 3), rig, "right")
    n = len(o)
    return uv.reshape(n, len(z), 2), ok.reshape(n, len(z)) & (t > 0)


def epipolar_curve_px(origin_mm, direction, z_mm, rig: Rig) -> np.ndarray:
    """A left-view ray's epipolar curve in the right view: the right-view pixels (S', 2) of the ray's points
    at the depths ``z_mm`` (S,) mm (``origin_mm`` (3,) mm and unit ``direction`` (3,) from
    :func:`psvs.optics.trace.trace_pixels`), in the order of ``z_mm``; points the right view does not see
    are left out (:func:`epipolar_curves_px` for one ray)."""
    uv, ok = epipolar_curves_px(origin_mm, direction, z_mm, rig)
    return uv[0][ok[0]]
