"""Plane optical surfaces: ray-plane intersection, mirror reflection, Snell refraction, finite extents.

Rays are rows: origins ``(N, 3)`` mm and unit directions ``(N, 3)``. Per-ray failures (parallel to a
plane, behind it, outside a mirror, total internal reflection) clear a ``valid`` mask of shape ``(N,)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from psvs.optics.rig import MirrorExtent

#: Tolerance, mm, by which a hit may lie outside a mirror's rectangle and still count as on it
#: (so the exact footprint of a designed mirror is not lost to rounding).
EXTENT_TOL_MM = 1e-9


@dataclass(frozen=True)
class Plane:
    """An oriented plane with an optional finite rectangle.

    Attributes
    ----------
    name : str
    point : ndarray, shape (3,)
        Anchor, mm: where the nominal axis of its path crosses it.
    normal : ndarray, shape (3,)
        Unit normal, facing the light that arrives along the nominal path.
    s_axis : ndarray, shape (3,)
        Unit in-plane horizontal axis (in the XZ plane, +Z component, for a mirror as designed).
    extent : MirrorExtent or None
        Rectangle in (s, t) about ``point``; None is an unbounded plane.
    t_axis : ndarray, shape (3,)
        Unit in-plane axis perpendicular to ``s_axis``: +Y for a mirror as designed (a leaning mirror
        tilts it).
    """

    name: str
    point: np.ndarray
    normal: np.ndarray
    s_axis: np.ndarray
    extent: MirrorExtent | None = None
    t_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))

    def local(self, points_mm: np.ndarray) -> np.ndarray:
        """In-plane coordinates (s, t) of points, shape (N, 2), mm."""
        rel = points_mm - self.point
        return np.stack([rel @ self.s_axis, rel @ self.t_axis], axis=1)

    def moved(self, R: np.ndarray, centre: np.ndarray, shift_mm: float = 0.0) -> "Plane":
        """The plane turned by the rotation matrix R (3, 3) about ``centre`` (3,), then moved by
        ``shift_mm`` along its turned normal (its rectangle moves with it)."""
        normal = R @ self.normal
        point = centre + R @ (self.point - centre) + shift_mm * normal
        return Plane(self.name, point, normal, R @ self.s_axis, self.extent, R @ self.t_axis)

    def contains(self, points_mm: np.ndarray) -> np.ndarray:
        """Mask (N,) of points (assumed on the plane) inside the rectangle; all True when unbounded."""
        if self.extent is None:
            return np.ones(len(points_mm), dtype=bool)
        rel = points_mm - self.point
        s = rel @ self.s_axis
        t = rel @ self.t_axis
        (s0, s1), (t0, t1) = self.extent.along_mm, self.extent.height_mm
        tol = EXTENT_TOL_MM
        return (s >= s0 - tol) & (s <= s1 + tol) & (t >= t0 - tol) & (t <= t1 + tol)

    def reflect_points(self, points_mm: np.ndarray) -> np.ndarray:
        """Mirror images of points, shape (N, 3): p - 2 ((p - a) . n) n."""
        return points_mm - 2.0 * ((points_mm - self.point) @ self.normal)[:, None] * self.normal

    def householder(self) -> np.ndarray:
        """The 3x3 reflection matrix I - 2 n n^T acting on directions."""
        return np.eye(3) - 2.0 * np.outer(self.normal, self.normal)


def intersect(origins_mm: np.ndarray, dirs: np.ndarray, plane: Plane):
    """Intersect rays with a plane.

    Returns
    -------
    t_mm : ndarray, shape (N,)
        Distance along each ray; NaN where the ray is parallel to the plane.
    points_mm : ndarray, shape (N, 3)
    ahead : ndarray of bool, shape (N,)
        The hit lies in front of the origin (t > 0).
    """
    denom = dirs @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (plane.point @ plane.normal - origins_mm @ plane.normal) / denom
    t[np.abs(denom) <= 1e-15] = np.nan
    points = origins_mm + t[:, None] * dirs
    return t, points, t > 0


def reflect(dirs: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Mirror reflection of unit directions (N, 3): d - 2 (d . n) n."""
    return dirs - 2.0 * (dirs @ normal)[:, None] * normal


def refract(dirs: np.ndarray, normal: np.ndarray, eta: float):
    """Snell refraction, vector form (n1 sin i = n2 sin t).

    Parameters
    ----------
    dirs : ndarray, shape (N, 3)
        Unit incident directions.
    normal : ndarray, shape (3,)
        Unit surface normal (either orientation).
    eta : float
        n1 / n2, ratio of the refractive index before to after the surface.

    Returns
    -------
    out : ndarray, shape (N, 3)
        Unit refracted directions; NaN rows at total internal reflection.
    valid : ndarray of bool, shape (N,)
    """
    cos_i = dirs @ normal
    side = -np.sign(cos_i)               # the normal, flipped to face the incoming ray, is side * normal
    cos_i = np.abs(cos_i)
    sin2_t = eta * eta * (1.0 - cos_i * cos_i)
    valid = sin2_t <= 1.0
    cos_t = np.sqrt(np.clip(1.0 - sin2_t, 0.0, None))
    out = eta * dirs
    out += ((eta * cos_i - cos_t) * side)[:, None] * normal
    if not valid.all():
        out[~valid] = np.nan
    return out, valid
