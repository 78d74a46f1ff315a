"""Measure the paper's accuracy pattern (Table I's columns): depth Z, circle diameters and the distance
between the first and last circle centres, from one complex image."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psvs.calibrate.targets import Ellipse, PatternDetection, detect_pattern
from psvs.measure.triangulate import triangulate, twin_rows
from psvs.optics.rig import Rig


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


def _rim_points(left: Ellipse, right: Ellipse, rig: Rig, model: str, rows: int = 15) -> np.ndarray:
    """3-D rim points (M, 3) of one circle: the ends of each row chord in the left view matched with the
    chord ends in the right view (epipolar rows), moved to the twin's true row (the plate shifts rows)."""
    b = max(left.axes_px) * 0.85
    out = []
    for v in np.linspace(left.centre_px[1] - b, left.centre_px[1] + b, rows):
        cl = left.row_crossings(v)
        cr = right.row_crossings(v)
        if cl is None or cr is None:
            continue
        lp = np.array([[cl[0], v], [cl[1], v]])
        rp = np.array([[cr[0], v], [cr[1], v]])
        v_r, ok = twin_rows(lp, rp, rig, model)         # the twin's true row
        for k in range(2):
            if not ok[k]:
                continue
            c2 = right.row_crossings(v_r[k])
            if c2 is None:
                continue
            rp[k] = [c2[k], v_r[k]]
        out.append(triangulate(lp, rp, rig, model=model).points_mm)
    return np.concatenate(out) if out else np.zeros((0, 3))


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
    diam = np.array([_circle_diameter(_rim_points(lft, rgt, rig, model)) for lft, rgt in zip(det.left, det.right)])
    return PatternMeasurement(float(centres[:, 2].mean()), diam, float(np.nanmean(diam)),
                              float(np.linalg.norm(centres[-1] - centres[0])), centres)
