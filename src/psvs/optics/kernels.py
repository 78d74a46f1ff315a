"""The ray tracer's per-ray loops as Numba kernels (compiled once per machine, kept in ``__pycache__``): undoing
the lens's distortion and the bounding-box pre-test of the blocking solids. Each is one pass over the rays
in place of NumPy's dozen temporary arrays; :mod:`psvs.optics.trace` and :mod:`psvs.optics.solids` call them
and keep the formulas' documentation."""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True, error_model="numpy")   # a zero radial factor gives inf, as NumPy did
def undistort_fixed_point(xd, k1, k2, p1, p2, k3, iterations, tol):  # pragma: no cover - compiled
    """Normalised undistorted points (N, 2) of distorted ones ``xd`` (N, 2): per point, the fixed-point
    iteration x <- (x_d - tangential(x)) / radial(x) until it moves by ``tol`` or less (at most
    ``iterations``); a NaN point stays NaN."""
    out = np.empty_like(xd)
    for i in range(xd.shape[0]):
        xd0, yd0 = xd[i, 0], xd[i, 1]
        x, y = xd0, yd0
        for _ in range(iterations):
            r2 = x * x + y * y
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            nx = (xd0 - 2.0 * p1 * x * y - p2 * (r2 + 2.0 * x * x)) / radial
            ny = (yd0 - p1 * (r2 + 2.0 * y * y) - 2.0 * p2 * x * y) / radial
            moved = abs(nx - x) > tol or abs(ny - y) > tol
            x, y = nx, ny
            if not moved:
                break
        out[i, 0], out[i, 1] = x, y
    return out


@nb.njit(cache=True, nogil=True)
def boxes_meet(p0s, p1s, lo, hi):  # pragma: no cover - compiled
    """Mask (N,) of segments p0s -> p1s (N, 3) whose axis-aligned bounding box meets the box [lo, hi] (3,)
    (a NaN coordinate meets nothing)."""
    out = np.zeros(p0s.shape[0], dtype=np.bool_)
    for i in range(p0s.shape[0]):
        meet = True
        for k in range(3):
            a, b = p0s[i, k], p1s[i, k]
            if np.isnan(a) or np.isnan(b) or max(a, b) < lo[k] or min(a, b) > hi[k]:
                meet = False
                break
        out[i] = meet
    return out
