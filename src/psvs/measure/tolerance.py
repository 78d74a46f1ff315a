"""Tolerance analysis for builders: how far each mirror's mounting error moves the two views.

For every mirror M1..M4 and each of its three pose errors (:class:`~psvs.optics.rig.MirrorError`: tilt a
about the vertical, tilt b out of vertical, shift along the normal), and for the camera turned in its mount
(``box_rotation``), the rig is built with that one error (a small step) and a grid of scene points over the
views' shared field and working depth is projected through it (exact optics). Two numbers say what the error
does before any calibration:

- **row disagreement** (px): how many rows a point's two twins move apart, |(v_l - v_r) - nominal|. The
  paper's matching (section III.3) and eq. (12) assume twins on one row;
- **depth error** (mm): the Z the *nominal* rig triangulates (exact model) from the moved pixels, minus the
  truth.

Both grow linearly with small errors, so each row also gives the error that costs 1 px of row disagreement:
the mounting tolerance for matching along rows without calibration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs.measure.triangulate import triangulate
from psvs.optics.project import in_image, project_points
from psvs.optics.rig import MIRROR_NAMES, MirrorError, Rig
from psvs.optics.trace import trace_pixels

#: Error steps: 0.1 deg for tilts and rotations, 0.1 mm for shifts (small enough to stay linear).
TILT_STEP_RAD = math.radians(0.1)
SHIFT_STEP_MM = 0.1

COMPONENTS = ("tilt a (about vertical)", "tilt b (out of vertical)", "shift (along normal)")
BOX_AXES = ("X", "Y", "Z")


@dataclass(frozen=True)
class Sensitivity:
    """What one error of ``step`` (rad for tilts/rotations, mm for shifts) does over the field.

    ``row_px_max``, ``row_px_mean``: row disagreement of the twins, px; ``depth_mm_mean``, ``depth_mm_max``:
    |Z error| of the nominal rig's exact triangulation, mm; ``per_px``: the error (rad or mm) that moves the
    twins 1 px apart at worst (inf when it does not move them)."""

    part: str
    component: str
    unit: str            # 'rad' or 'mm'
    step: float
    row_px_max: float
    row_px_mean: float
    depth_mm_mean: float
    depth_mm_max: float

    @property
    def per_px(self) -> float:
        return self.step / self.row_px_max if self.row_px_max > 0 else math.inf


def field_points(rig: Rig, near_mm: float, far_mm: float, n_u: int = 9, n_v: int = 7, n_z: int = 3) -> np.ndarray:
    """(N, 3) mm: points on the left view's pixel grid (n_u x n_v over the image) at n_z depths near..far,
    kept where the right view sees them too (the shared field)."""
    w, h = rig.camera.image_size_px
    u, v = np.meshgrid(np.linspace(0.05 * w, 0.95 * w, n_u), np.linspace(0.05 * h, 0.95 * h, n_v))
    rays = trace_pixels(np.column_stack([u.ravel(), v.ravel()]), rig, "left")
    pts = []
    for z in np.linspace(near_mm, far_mm, n_z):
        t = (z - rays.origins_mm[:, 2]) / rays.dirs[:, 2]
        pts.append(rays.origins_mm + t[:, None] * rays.dirs)
    pts = np.concatenate(pts)[np.tile(rays.valid, n_z)]
    uv_r, ok = project_points(pts, rig, "right")
    return pts[ok & in_image(uv_r, rig)]


def _effect(nominal: Rig, built: Rig, pts: np.ndarray, base_rows: np.ndarray):
    uv_l, ok_l = project_points(pts, built, "left")
    uv_r, ok_r = project_points(pts, built, "right")
    ok = ok_l & ok_r
    rows = np.abs((uv_l[:, 1] - uv_r[:, 1]) - base_rows)[ok]
    tri = triangulate(uv_l[ok], uv_r[ok], nominal, model="exact")
    dz = np.abs(tri.points_mm[tri.valid, 2] - pts[ok][tri.valid, 2])
    if not len(rows) or not len(dz):
        raise ValueError("no point of the field is seen in both views of the moved rig")
    return float(rows.max()), float(rows.mean()), float(dz.mean()), float(dz.max())


def tolerance_analysis(rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0,
                       tilt_step_rad: float = TILT_STEP_RAD, shift_step_mm: float = SHIFT_STEP_MM) -> list[Sensitivity]:
    """One :class:`Sensitivity` per mirror error (M1..M4 x tilt a, tilt b, shift) and per camera-mount
    rotation (about X, Y, Z), each applied alone on top of ``rig`` (as designed or as built)."""
    if not (0 < near_mm < far_mm and math.isfinite(far_mm)):
        raise ValueError(f"working range must satisfy 0 < near < far (finite), got {near_mm}..{far_mm} mm")
    if not (tilt_step_rad > 0 and shift_step_mm > 0):
        raise ValueError("tilt and shift steps must be > 0")
    pts = field_points(rig, near_mm, far_mm)
    if len(pts) < 3:
        raise ValueError("the views share too little field in the working range for a tolerance analysis")
    uv_l, _ = project_points(pts, rig, "left")
    uv_r, _ = project_points(pts, rig, "right")
    base_rows = uv_l[:, 1] - uv_r[:, 1]
    out = []
    for name in MIRROR_NAMES:
        now = getattr(rig.mirrors, f"{name}_error")
        for k, comp in enumerate(COMPONENTS):
            tilt = list(now.tilt_rad)
            shift = now.shift_mm
            if k < 2:
                tilt[k] += tilt_step_rad
            else:
                shift += shift_step_mm
            built = rig.with_errors({name: MirrorError(tuple(tilt), shift)})
            step, unit = (tilt_step_rad, "rad") if k < 2 else (shift_step_mm, "mm")
            out.append(Sensitivity(name.upper(), comp, unit, step, *_effect(rig, built, pts, base_rows)))
    for k, axis in enumerate(BOX_AXES):
        rot = list(rig.mirrors.box_rotation_rad)
        rot[k] += tilt_step_rad
        built = rig.replace(box_rotation_rad=tuple(rot))
        out.append(Sensitivity("mirror box", f"turned about {axis}", "rad", tilt_step_rad,
                               *_effect(rig, built, pts, base_rows)))
    return out
