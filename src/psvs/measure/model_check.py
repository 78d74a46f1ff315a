"""Whether a closed-form model (the paper's eqs. 12-14, or eqs. 15-17 with the plate) may stand for a build.

The closed forms triangulate through the paper's ideal geometry: parallel virtual cameras, a distortion-free
lens. A build's rig file states what departs from it (mirror tilts and shifts, a turned box, the lens's
distortion), and the exact model traces through all of it. Asked for a closed form on a build, psvs answered
with it: fig. 9's pattern at 900 mm through the `misaligned` build read 892.7 mm with the paper's model and
903.2 mm with refraction's (exact: 900.0), every pattern check passed (an adversarial trial, 2026-12-05). A closed form
is not wrong by itself: on the paper's geometry the paper's model is the paper's (about 1 % off for the plate
it leaves out, eq. 15 corrects it). What a build adds is.

:func:`check_closed_form` draws points over the view's field at depths over the working range, projects them
through the rig exactly and triangulates their pixels with the model, on the build and on the same rig as
designed (no mirror error, no box turn, no distortion): where the build's depth error exceeds the design's by
more than a :data:`~psvs.measure.triangulate.MATCH_SIGMA_PX` disparity moves the depth, the model is refused
for this rig, naming the figure (the exact model is the default on a build).
"""
from __future__ import annotations

import numpy as np

from psvs.measure.triangulate import MATCH_SIGMA_PX, default_model, depth_sigma_mm, triangulate
from psvs.optics.project import in_image, project_points
from psvs.optics.rectify import needs_rectification
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels

#: Points a side of the field's grid, and depths over the working range, the check triangulates.
GRID_SIDE = 7
DEPTHS = 5


def designed(rig: Rig) -> Rig:
    """``rig`` as designed: no mirror error, the box not turned, the lens without distortion."""
    return rig.designed_mirrors().replace(distortion=(0.0,) * len(rig.camera.distortion))


def field_points(rig: Rig, near_mm: float, far_mm: float) -> np.ndarray:
    """Points (N, 3) mm seen by both views of ``rig``: the left view's pixels on a :data:`GRID_SIDE` grid over
    the middle 80 % of the image, traced to :data:`DEPTHS` depths over near..far mm, kept where the right view
    sees them too."""
    w, h = rig.camera.image_size_px
    u, v = np.meshgrid(np.linspace(0.1, 0.9, GRID_SIDE) * (w - 1), np.linspace(0.1, 0.9, GRID_SIDE) * (h - 1))
    rays = trace_pixels(np.column_stack([u.ravel(), v.ravel()]), rig, "left")
    pts = []
    for z in np.linspace(near_mm, far_mm, DEPTHS):
        t = (z - rays.origins_mm[:, 2]) / rays.dirs[:, 2]
        pts.append((rays.origins_mm + t[:, None] * rays.dirs)[rays.valid & (t > 0)])
    pts = np.concatenate(pts)
    right, ok = project_points(pts, rig, "right")
    return pts[ok & in_image(right, rig)]


def closed_form_excess(rig: Rig, model: str, near_mm: float, far_mm: float) -> tuple[float, float, float]:
    """How far the closed form ``model`` ('paper' or 'refraction') triangulates points of the build ``rig`` over
    near..far mm beyond what it does on the rig as designed (:func:`designed`), against the depth a
    :data:`~psvs.measure.triangulate.MATCH_SIGMA_PX` disparity moves: (the worst excess over that move (mm;
    <= 0: the model stands), the build's depth error there (mm), its depth (mm)); (-inf, NaN, NaN) when no point
    of the range is seen by both views."""
    pts = field_points(rig, near_mm, far_mm)
    if not len(pts):                 # no point both views see over the range: nothing to weigh the model on
        return float("-inf"), float("nan"), float("nan")
    ideal = designed(rig)
    out = []
    for r in (rig, ideal):
        left, okl = project_points(pts, r, "left")
        right, okr = project_points(pts, r, "right")
        z = np.full(len(pts), np.nan)
        ok = okl & okr
        tri = triangulate(left[ok], right[ok], r, model=model)
        z[np.flatnonzero(ok)[tri.valid]] = tri.points_mm[tri.valid, 2]
        out.append((z, left, right))
    (z_b, left, right), (z_i, _, _) = out
    move = depth_sigma_mm(left, right, rig, model="exact", sigma_px=MATCH_SIGMA_PX)
    err_b, err_i = np.abs(z_b - pts[:, 2]), np.abs(z_i - pts[:, 2])
    excess = np.where(np.isfinite(err_b), err_b - np.nan_to_num(err_i, nan=0.0) - move, np.inf)
    k = int(np.argmax(excess))
    return float(excess[k]), float(err_b[k]), float(pts[k, 2])


def check_closed_form(rig: Rig, model: str | None, near_mm: float = 400.0, far_mm: float = 1200.0) -> None:
    """ValueError (one sentence, the figures) when ``model`` is a closed form ('paper', 'refraction') and ``rig``
    a build on which it errs beyond a match's noise (:func:`closed_form_excess`); nothing for the exact model,
    None (the rig's default) or the paper's geometry."""
    if model in (None, "exact") or not needs_rectification(rig):
        return
    excess, err, z = closed_form_excess(rig, model, near_mm, far_mm)
    if excess > 0:
        raise ValueError(f"the {model} model leaves out what this rig file states of its build (mirror tilts and "
                         f"shifts, the box's turn, the lens's distortion): over {near_mm:g}-{far_mm:g} mm it puts a "
                         f"point at {z:.0f} mm {err:.2f} mm off, beyond what a {MATCH_SIGMA_PX:g} px match moves it "
                         "and what the model errs on the design; use --model exact (the default on a build)")


def closed_form_depth_error(rig: Rig, model: str, near_mm: float = 400.0,
                            far_mm: float = 1200.0) -> tuple[float, float]:
    """The closed form ``model``'s own depth error on ``rig`` (relative, Z_model / Z - 1) over near..far mm: the
    lowest and the highest over :func:`field_points` projected exactly through the rig and triangulated with
    the model; (0, 0) for the exact model or no point seen. On the paper's geometry the paper's model reads
    about 1 % short (eq. 12 leaves the plate out: -0.8 to -1.8 % on the default rig; an adversarial trial,
    2026-12-07)."""
    if model == "exact":
        return 0.0, 0.0
    pts = field_points(rig, near_mm, far_mm)
    left, okl = project_points(pts, rig, "left")
    right, okr = project_points(pts, rig, "right")
    ok = okl & okr
    tri = triangulate(left[ok], right[ok], rig, model=model)
    rel = tri.points_mm[tri.valid, 2] / pts[ok][tri.valid, 2] - 1.0
    return (float(rel.min()), float(rel.max())) if len(rel) else (0.0, 0.0)


#: A closed form's own depth error on the rig beyond this (relative) is said beside its answers, and `triangulate`
#: counts it in each point's sigma (the refraction model's -0.11 % at 1200 mm on the default rig is within a 0.1 px
#: match's move there; the paper's model's 0.8-1.8 % is 10 of them).
MODEL_ERROR_NOTE = 5e-3


def model_error_note(rig: Rig, model: str | None, near_mm: float = 400.0, far_mm: float = 1200.0) -> str:
    """One line saying how far the closed form ``model`` (None: the rig's default, which the commands then use)
    reads depth off on ``rig`` over near..far mm, when more than :data:`MODEL_ERROR_NOTE` anywhere; '' otherwise
    (and for the exact model)."""
    model = model or default_model(rig)
    if model == "exact":
        return ""
    lo, hi = closed_form_depth_error(rig, model, near_mm, far_mm)
    if max(abs(lo), abs(hi)) <= MODEL_ERROR_NOTE:
        return ""
    return (f"the {model} model reads depth {100 * lo:+.2f} to {100 * hi:+.2f} % off on this rig over "
            f"{near_mm:g}-{far_mm:g} mm ({'eq. 12 leaves the plate out' if model == 'paper' else 'its closed form'}"
            "; --model exact traces the glass)")
