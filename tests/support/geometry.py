"""Geometry the tests of several packages share: the examples folder, 3-D points over the whole field, the best
rigid motion (Kabsch) and a calibrated rig's reconstruction errors against the true build."""
import math
from pathlib import Path

import numpy as np

from psvs import default_rig

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def whole_field_points(rig, n_side=9, depths=(400.0, 600.0, 800.0, 1000.0, 1200.0)):
    """Points over the whole field seen by *both* views, at the given depths (mm), shape (N, 3)."""
    pts = []
    a_x, a_y = rig.camera.half_fov_rad
    for z in depths:
        half_w = (z - rig.virtual_z_mm) * math.tan(a_x) - rig.mirrors.baseline_mm / 2
        half_h = (z - rig.virtual_z_mm) * math.tan(a_y)
        gx, gy = np.meshgrid(np.linspace(-0.99, 0.99, n_side), np.linspace(-0.99, 0.99, n_side))
        pts.append(np.column_stack([gx.ravel() * half_w, gy.ravel() * half_h, np.full(gx.size, z)]))
    return np.concatenate(pts)


def kabsch(src: np.ndarray, dst: np.ndarray):
    """Rotation (3, 3) and translation (3,) minimising |R src + t - dst| (independent of psvs)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    U, _, Vt = np.linalg.svd((src - cs).T @ (dst - cd))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, cd - R @ cs


def reconstruction_errors(calibrated, true_rig, depths=(400.0, 600.0, 800.0, 1000.0, 1200.0), scale=1.0,
                          missing_ok=False):
    """Triangulate the true correspondences of points over the whole common field (400-1200 mm) with a
    calibrated rig (exact model). Returns (3-D errors in frame C, mm; 3-D errors after the best rigid
    motion, mm; the points (N, 3)). Images cannot fix frame C's placement behind the mirrors completely
    (docs/calibration.md): the second number is the reconstruction's own accuracy. ``scale`` multiplies
    the reconstruction first (to take out a known scale error). ``missing_ok``: points the calibrated rig
    does not triangulate (its field's edges) have NaN errors, the rigid motion fitted on the others."""
    from psvs.measure.triangulate import triangulate
    from psvs.optics.project import in_image, project_points
    pts = whole_field_points(default_rig(), n_side=9, depths=depths)
    left, okl = project_points(pts, true_rig, "left")
    right, okr = project_points(pts, true_rig, "right")
    seen = okl & okr & in_image(left, true_rig) & in_image(right, true_rig)
    got = scale * triangulate(left[seen], right[seen], calibrated, model="exact").points_mm
    raw = np.linalg.norm(got - pts[seen], axis=1)
    found = np.isfinite(raw) if missing_ok else np.ones(len(raw), bool)
    R, t = kabsch(got[found], pts[seen][found])
    aligned = np.linalg.norm(got @ R.T + t - pts[seen], axis=1)
    return raw, aligned, pts[seen]
