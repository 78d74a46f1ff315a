"""Whether a calibration fits its card views as well as their detections' own noise allows
(docs/right-or-refuse.md).

A bundle adjustment's reprojection RMS alone proves nothing: the detections carry noise of their own (a few
hundredths of a pixel on a rendered view, a tenth or more on a real camera), and a fitted rig is only the
views' rig when what it leaves is that noise. The noise is read from the residuals themselves: along each row
and column of the card, the second difference of three neighbouring points' residuals, r[i] - 2 r[i+1] + r[i+2],
cancels the smooth field that a wrong model leaves over a card (views turned by 180 degrees or mirrored: every
parameter is fitted, none is implausible, and RMS 0.20 px stood against the views' 0.026 px of noise; a fit
stopped in a wrong minimum: 0.30 px) and keeps white noise (its variance is 6 sigma^2 for each coordinate).
A fit whose RMS exceeds :data:`MISFIT_RATIO` times that noise, and :data:`MISFIT_FLOOR_PX`, is refused. Good
calibrations read a ratio of 0.91-0.99 here (four sets of card views through the misaligned build).

Only card views are read (a robot sweep's single row of circles is too short to tell the two apart).
"""
from __future__ import annotations

import math

import numpy as np

from psvs.errors import MeasurementError

__all__ = ["MISFIT_FLOOR_PX", "MISFIT_RATIO", "check_misfit", "lattice_noise_px"]

#: A fit whose reprojection RMS (one coordinate's) exceeds this many times the detections' noise does not fit
#: its views: the model, or the views, are wrong.
MISFIT_RATIO = 3.0
#: ... and exceeds this (px): below it, what the model leaves is below what any use of the rig would see.
MISFIT_FLOOR_PX = 0.05
#: The fewest second differences the noise is read from (fewer: not tested).
MIN_DIFFERENCES = 30


def lattice_noise_px(grids, residuals: dict) -> tuple[float, int]:
    """(one coordinate's noise sigma px, the number of second differences it was read from) of the card views
    ``grids`` (:class:`psvs.calibrate.bundle.GridView`, their ``object_mm`` on a square lattice) from the
    bundle's ``residuals`` (name -> (left (n, 2), right (n, 2)) px, row k the view's point k): each row and
    column's second differences of three neighbouring points, both views (module docstring); NaN with none."""
    d2 = []
    for g in grids:
        if g.name not in residuals or len(g.object_mm) < 3:
            continue
        xy = np.asarray(g.object_mm, dtype=float)[:, :2]
        step = np.array([_step(xy[:, 0]), _step(xy[:, 1])])       # the lattice's spacing along each axis
        index = {tuple(k): i for i, k in enumerate(np.round((xy - xy.min(axis=0)) / step).astype(int))}
        triples = [(i, index.get((a + da, b + db)), index.get((a + 2 * da, b + 2 * db)))
                   for (a, b), i in index.items() for da, db in ((1, 0), (0, 1))]
        triples = np.array([t for t in triples if t[1] is not None and t[2] is not None], dtype=int).reshape(-1, 3)
        for r in residuals[g.name]:
            r = np.asarray(r, dtype=float)
            d2.append(r[triples[:, 0]] - 2 * r[triples[:, 1]] + r[triples[:, 2]])
    d = np.concatenate(d2) if d2 else np.zeros((0, 2))
    if not len(d):
        return float("nan"), 0
    return math.sqrt(float(np.mean(d ** 2)) / 6.0), len(d)


def _step(coords: np.ndarray) -> float:
    """The smallest spacing between distinct values of ``coords`` (inf for one value)."""
    d = np.diff(np.unique(np.round(coords, 6)))
    d = d[d > 1e-6]
    return float(d.min()) if len(d) else math.inf


def check_misfit(bundle, grids, what: str) -> None:
    """MeasurementError when the ``bundle`` (:class:`psvs.calibrate.bundle.BundleResult`) fits its card views
    ``grids`` worse than their noise allows (module docstring); ``what`` names the calibration."""
    noise, n = lattice_noise_px(grids, bundle.residuals)
    if n < MIN_DIFFERENCES or not math.isfinite(noise):
        return
    if bundle.rms_px > max(MISFIT_RATIO * noise, MISFIT_FLOOR_PX):
        raise MeasurementError(
            f"{what} does not fit its views: reprojection RMS {bundle.rms_px:.3f} px against the detections' own "
            f"noise {noise:.3f} px (read from {n} second differences along the card's rows and columns; a fit "
            f"beyond {MISFIT_RATIO:g} times it leaves a pattern no noise makes): views turned or mirrored, of "
            "another rig, or a lens the model cannot describe")
