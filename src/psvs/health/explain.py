"""Which mirrors' tilts best explain a drift the check measured (``psvs check``; as ``psvs adjust`` names
screws).

The judged tiles' twins are triangulated through the calibration (exact optics): a scene point P per tile.
Tilting mirror m by a small angle about either of its axes (:class:`psvs.optics.rig.MirrorError`'s a:
about the vertical; b: out of vertical) moves P's two images; read through the calibration's rectification,
their rows part by a field over the tiles: a column of the Jacobian (finite differences of
:data:`STEP_DEG`). Each mirror's two tilts are fitted alone to the measured offsets (least squares), and
the mirrors are ranked by what is left (a tilt the rows barely see, :data:`RCOND`, is left at 0); those
within :data:`SAME_PX` of the best cannot be told apart by
the rows (M1 and M3 turn the same path, for instance) and are named together.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs.dense.rig_cache import rectification
from psvs.health.check import HealthCheck, judged_pairs_px
from psvs.measure.triangulate import triangulate
from psvs.optics.project import project_points
from psvs.optics.rig import MIRROR_NAMES, MirrorError, Rig

#: The tilt step (deg) of the finite differences.
STEP_DEG = 0.02
#: A combination of a mirror's two tilts that moves the rows less than this share of the one that moves them
#: most is not fitted (minimum norm: a turn about the vertical moves a view along its rows, barely across).
RCOND = 0.1
#: Mirrors whose fits leave within this much (px, RMS) of the best one's are named together.
SAME_PX = 0.05


@dataclass(frozen=True)
class Explanation:
    """One mirror's tilts fitted alone to the measured offsets: ``mirror`` ("m1".."m4"), ``tilt_deg`` (a, b)
    and the RMS ``residual_px`` they leave of the field."""

    mirror: str
    tilt_deg: tuple[float, float]
    residual_px: float

    def as_dict(self) -> dict:
        """JSON-ready (``psvs check --json``'s ``explained_by`` entries, the web page's)."""
        return {"mirror": self.mirror, "tilt_deg": list(self.tilt_deg), "residual_px": self.residual_px}


def _rows(rig: Rig, rect, points_mm: np.ndarray) -> np.ndarray:
    """Each point's twin row offset (n,) through ``rig``, read on the calibration's rectified grids."""
    out = []
    for view in ("left", "right"):
        uv, ok = project_points(points_mm, rig, view)
        uv[~ok] = np.nan
        out.append(uv if rect is None else rect.to_rectified(uv, view))
    return out[1][:, 1] - out[0][:, 1]


def tilted(rig: Rig, mirror: str, a_rad: float, b_rad: float) -> Rig:
    """``rig`` with ``mirror`` tilted a further (a, b) rad about its axes."""
    e = getattr(rig.mirrors, f"{mirror}_error")
    return rig.with_errors({mirror: MirrorError((e.tilt_rad[0] + a_rad, e.tilt_rad[1] + b_rad), e.shift_mm)})


def explain_offsets(check: HealthCheck, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> list[Explanation]:
    """The mirrors ranked by how well their tilts alone explain the check's fitted field (module docstring),
    read through the rectification the check read through (``rig``'s over near..far mm). Empty when the
    check judged nothing."""
    if check.tiles == 0 or not np.all(np.isfinite(check.fitted_px)):
        return []
    rect = rectification(rig, near_mm, far_mm)
    left, right = judged_pairs_px(check, rig, near_mm, far_mm)
    pts = triangulate(left, right, rig, model="exact")
    keep = pts.valid
    p, y = pts.points_mm[keep], check.fitted_px[keep]
    if len(p) < 6:
        return []
    base = _rows(rig, rect, p)
    h = math.radians(STEP_DEG)
    out = []
    for m in MIRROR_NAMES:
        J = np.column_stack([(_rows(tilted(rig, m, h, 0.0), rect, p) - base) / h,
                             (_rows(tilted(rig, m, 0.0, h), rect, p) - base) / h])
        ok = np.all(np.isfinite(J), axis=1)
        x = np.linalg.lstsq(J[ok], y[ok], rcond=RCOND)[0]      # a tilt the rows barely see is left at 0
        r = y[ok] - J[ok] @ x
        out.append(Explanation(m, (math.degrees(x[0]), math.degrees(x[1])), float(np.sqrt(np.mean(r ** 2)))))
    return sorted(out, key=lambda e: e.residual_px)


def explain_drift(check: HealthCheck, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> list[Explanation]:
    """:func:`explain_offsets` of a check that found a drift; empty for a healthy one or one that cannot judge
    (nothing to explain): what ``psvs check`` and the web page's Check step name."""
    return explain_offsets(check, rig, near_mm, far_mm) if check.verdict == "drifted" else []


def explanation_line(found: list[Explanation], tolerance_px: float | None = None) -> str:
    """One line: the best-explaining mirror(s) and their tilts, e.g. "m3 (a +0.00, b +0.06 deg; leaves
    0.05 px), as well: m1 (...)"; when even the best leaves more than ``tolerance_px`` of the field, that no
    one mirror explains it (naming one would be a guess)."""
    if not found:
        return "no mirror named: nothing judged"
    text = lambda e: (f"{e.mirror.upper()} (a {e.tilt_deg[0]:+.3f}, b {e.tilt_deg[1]:+.3f} deg; leaves "  # noqa: E731
                      f"{e.residual_px:.2f} px)")
    if tolerance_px is not None and found[0].residual_px > tolerance_px:
        return (f"no one mirror's tilts: the best, {text(found[0])}, leaves more than the {tolerance_px:g} px "
                "tolerance (several mirrors or the box moved, or frames of another rig)")
    same = [e for e in found[1:] if e.residual_px <= found[0].residual_px + SAME_PX]
    return text(found[0]) + ("" if not same else "; the rows cannot tell it from " + ", ".join(map(text, same)))
