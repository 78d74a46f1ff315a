"""Measure the paper's accuracy pattern (Table I's columns): depth Z, circle diameters and the distance
between the first and last circle centres, from one complex image."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psvs.calibrate.targets import Ellipse, PatternDetection, detect_pattern
from psvs.measure.triangulate import triangulate
from psvs.optics.project import project_points
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels


@dataclass(frozen=True, eq=False)
class PatternMeasurement:
    """Z_mm: mean depth of the circle centres; diameters_mm (n,); diameter_mm: their mean;
    first_last_distance_mm: |c_first - c_last|; centres_mm (n, 3), frame C."""

    Z_mm: float
    diameters_mm: np.ndarray
    diameter_mm: float
    first_last_distance_mm: float
    centres_mm: np.ndarray

    def to_dict(self) -> dict:
        return {"Z_mm": self.Z_mm, "diameter_mm": self.diameter_mm,
                "first_last_distance_mm": self.first_last_distance_mm,
                "diameters_mm": self.diameters_mm.tolist(), "centres_mm": self.centres_mm.tolist()}


def _implicit(e: Ellipse, uv: np.ndarray) -> np.ndarray:
    """The ellipse's implicit function at pixels uv (..., 2): < 0 inside, 0 on the rim, > 0 outside."""
    a, b = e.axes_px
    c, s = np.cos(e.angle_rad), np.sin(e.angle_rad)
    x, y = uv[..., 0] - e.centre_px[0], uv[..., 1] - e.centre_px[1]
    return ((x * c + y * s) / a) ** 2 + ((-x * s + y * c) / b) ** 2 - 1.0


def epipolar_twins(left_px: np.ndarray, right: Ellipse, rig: Rig, z_mm: tuple[float, float], first: np.ndarray,
                   samples: int = 161) -> np.ndarray:
    """Where the epipolar curves of left-view rim points cross the right view's ellipse, (N, 2) px (NaN where
    they do not): each left pixel's ray (exact optics, any build) is sampled at depths z_mm[0]..z_mm[1],
    projected into the right view, and the crossing refined on that curve; ``first`` (N,) bool picks the
    crossing of smaller u (the rim's left end), else the larger."""
    n = len(left_px)
    rays = trace_pixels(left_px, rig, "left")
    z = np.linspace(*z_mm, samples)
    t = (z[None, :] - rays.origins_mm[:, 2:3]) / rays.dirs[:, 2:3]
    pts = rays.origins_mm[:, None, :] + t[..., None] * rays.dirs[:, None, :]
    uv, ok = project_points(pts.reshape(-1, 3), rig, "right")
    uv = uv.reshape(n, samples, 2)
    f = np.where(ok.reshape(n, samples), _implicit(right, uv), np.nan)
    out = np.full((n, 2), np.nan)
    for k in range(n):
        if not rays.valid[k]:
            continue
        cross = np.flatnonzero(np.sign(f[k, :-1]) * np.sign(f[k, 1:]) < 0)
        if len(cross) == 0:
            continue
        at = [c + f[k, c] / (f[k, c] - f[k, c + 1]) for c in cross]          # linear in the sample index
        pos = [uv[k, c] + (a - c) * (uv[k, c + 1] - uv[k, c]) for c, a in zip(cross, at)]
        out[k] = min(pos, key=lambda q: q[0]) if first[k] else max(pos, key=lambda q: q[0])
    return out


def _rim_points(left: Ellipse, right: Ellipse, rig: Rig, model: str, z_mm: float, rows: int = 15) -> np.ndarray:
    """3-D rim points (M, 3) of one circle: both ends of row chords of the left view's ellipse, each paired
    with the point where its epipolar curve (the exact optics of the rig as built: rows of the two views
    need not agree) crosses the right view's ellipse, near the circle's depth ``z_mm``."""
    b = max(left.axes_px) * 0.85
    ends, first = [], []
    for v in np.linspace(left.centre_px[1] - b, left.centre_px[1] + b, rows):
        cl = left.row_crossings(v)
        if cl is not None:
            ends += [[cl[0], v], [cl[1], v]]
            first += [True, False]
    if not ends:
        return np.zeros((0, 3))
    lp = np.array(ends)
    rp = epipolar_twins(lp, right, rig, (z_mm - 80.0, z_mm + 80.0), np.array(first))
    keep = np.all(np.isfinite(rp), axis=1)
    return triangulate(lp[keep], rp[keep], rig, model=model).points_mm


def _circle_diameter(points: np.ndarray) -> float:
    """Diameter (mm) of the least-squares circle through 3-D points (M, 3): PCA plane, Kasa circle fit."""
    p = points[np.all(np.isfinite(points), axis=1)]
    if len(p) < 5:
        return float("nan")
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c)
    xy = (p - c) @ vt[:2].T
    A = np.column_stack([2 * xy, np.ones(len(xy))])
    rhs = (xy ** 2).sum(axis=1)
    (x0, y0, k), *_ = np.linalg.lstsq(A, rhs, rcond=None)
    return float(2 * np.sqrt(k + x0 * x0 + y0 * y0))


def measure_pattern(grey: np.ndarray, rig: Rig, model: str = "exact", count: int = 5,
                    detection: PatternDetection | None = None) -> PatternMeasurement:
    """Table I's columns for one complex image of the pattern (see the module docstring)."""
    det = detection or detect_pattern(grey, count)
    lc = np.array([e.centre_px for e in det.left])
    rc = np.array([e.centre_px for e in det.right])
    centres = triangulate(lc, rc, rig, model=model).points_mm
    if not np.all(np.isfinite(centres)):
        raise ValueError("a circle's two views do not triangulate (disparity <= 0): not a PSVS pattern image")
    diam = np.array([_circle_diameter(_rim_points(lft, rgt, rig, model, float(c[2])))
                     for lft, rgt, c in zip(det.left, det.right, centres)])
    return PatternMeasurement(float(centres[:, 2].mean()), diam, float(np.nanmean(diam)),
                              float(np.linalg.norm(centres[-1] - centres[0])), centres)
