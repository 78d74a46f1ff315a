"""The seam path model: seam points (base frame) by arc length, a smoothing spline, look-ahead, bridging.

Each valid frame adds one knot (the groove root the sensor fitted). Its arc length is the previous
knot's plus the step projected on the measured tangent (lateral noise does not lengthen the path). The
path is a cubic smoothing spline per coordinate (scipy's ``make_smoothing_spline``) over the knots of a
window that starts 30 mm behind the torch; its penalty weight is lam = L^4 / h (h the mean knot spacing), so
that it averages over about ``smoothing_mm`` = L of seam whatever the speed (generalised cross-validation
would choose it per fit, but costs ~50 ms a fit: too slow for a 25 Hz loop). Beyond the last
knot the model continues along the end tangent: that is how a gap is bridged (up to ``bridge_mm``).
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import make_smoothing_spline

#: How far behind the torch the spline's window starts, mm (6 smoothing lengths).
BEHIND_MM = 30.0


class SeamPath:
    """Knots (s, point) along the seam and the spline through them.

    Parameters
    ----------
    start_mm : (3,) the taught start point of the seam (base frame, mm): the first knot, s = 0.
    start_tangent : (3,) the taught direction of travel there (used until a second knot exists).
    min_spacing_mm : knots closer than this along the seam to the last one are not added.
    """

    def __init__(self, start_mm, start_tangent, min_spacing_mm: float = 0.2, smoothing_mm: float = 5.0):
        t = np.asarray(start_tangent, float)
        self.start_tangent = t / np.linalg.norm(t)
        self.s = [0.0]
        self.p = [np.asarray(start_mm, float)]
        self.min_spacing_mm = min_spacing_mm
        self.smoothing_mm = smoothing_mm
        self._fit = None
        self._knots = (np.array(self.s), np.array(self.p))

    @property
    def s_end(self) -> float:
        """Arc length of the last knot (the last seam point seen), mm."""
        return self.s[-1]

    def add(self, point_mm, tangent) -> bool:
        """Add a seen seam point with its unit tangent; False (not added) when it is not ahead of the last
        knot by ``min_spacing_mm``."""
        point_mm = np.asarray(point_mm, float)
        s_new = self.arc_of(point_mm, tangent)
        if s_new - self.s[-1] < self.min_spacing_mm:
            return False
        self.s.append(s_new)
        self.p.append(point_mm)
        self._fit = None
        return True

    def arc_of(self, point_mm, tangent) -> float:
        """The arc length a new knot at ``point_mm`` gets: the last knot's plus the step projected on the
        tangent (the straight distance from the start point for the first seen knot)."""
        step = np.asarray(point_mm, float) - self.p[-1]
        return self.s[-1] + (float(step @ tangent) if len(self.s) > 1 else float(np.linalg.norm(step)))

    def fit(self, s_from: float) -> None:
        """Refit the spline over the knots from ``s_from`` - ``BEHIND_MM`` on (call before evaluating). The
        window reaches well behind the torch (``s_from``): a knot leaving it changes the fit only where
        the torch has already been."""
        s = np.asarray(self.s)
        keep = np.flatnonzero(s >= s_from - BEHIND_MM)
        first = max(0, keep[0] - 1) if len(keep) else len(s) - 1
        S, P = s[first:], np.asarray(self.p[first:])
        if len(S) >= 5:
            lam = self.smoothing_mm ** 4 / float(np.mean(np.diff(S)))
            self._fit = [make_smoothing_spline(S, P[:, k], lam=lam) for k in range(3)]
        else:
            self._fit = None
        self._knots = (S, P)

    def _eval(self, s: float, nu: int = 0) -> np.ndarray:
        S, P = self._knots
        if self._fit is not None:
            return np.array([f(s, nu) for f in self._fit])
        if len(S) == 1:
            return P[0] if nu == 0 else self.start_tangent
        if nu == 0:
            return np.array([np.interp(s, S, P[:, k]) for k in range(3)])
        i = int(np.clip(np.searchsorted(S, s) - 1, 0, len(S) - 2))
        d = (P[i + 1] - P[i]) / (S[i + 1] - S[i])
        return d

    def position(self, s: float) -> np.ndarray:
        """The seam at arc length s, (3,) mm: the spline within the knots, the end tangent beyond the last
        (bridging), the first knot before the start."""
        S, _ = self._knots
        if s > S[-1]:
            return self._eval(S[-1]) + (s - S[-1]) * self.tangent(S[-1])
        return self._eval(max(s, S[0]))

    def tangent(self, s: float) -> np.ndarray:
        """Unit tangent (3,) at arc length s (clamped to the knots)."""
        S, _ = self._knots
        d = self._eval(float(np.clip(s, S[0], S[-1])), 1)
        return d / np.linalg.norm(d)
