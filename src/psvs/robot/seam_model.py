"""The seam path model: seam points (base frame) by arc length, a local quadratic fit, look-ahead, bridging.

Each valid frame adds one knot (the groove root the sensor fitted). Its arc length is the previous
knot's plus the step projected on the measured tangent (lateral noise does not lengthen the path). The
path at arc length s is a local quadratic regression (LOESS of degree 2, Cleveland 1979) of the knots
within ``2 * smoothing_mm`` of s, weighted by the tricube kernel: each coordinate's quadratic in the arc
length, evaluated at s (its slope is the tangent). The window widens where one side holds fewer knots
than half a full window (across a gap, toward the last knot), so the fit never extrapolates a few noisy
knots. A quadratic reproduces a seam's curvature, so the fit has no bias where the knots end on one side
(a smoothing spline's natural end conditions straighten a curved seam toward its last knot: 0.25 mm on a
seam of radius 150 mm, exactly where the torch stops).
Beyond the last knot the model continues along the end tangent: that is how a gap is bridged (up to
``bridge_mm``).
"""
from __future__ import annotations

import numpy as np

#: How far behind the torch the knots are kept for the fit, mm (beyond the kernel's reach).
BEHIND_MM = 30.0


class SeamPath:
    """Knots (s, point) along the seam and the local fit through them.

    Parameters
    ----------
    start_mm : (3,) the taught start point of the seam (base frame, mm): the first knot, s = 0.
    start_tangent : (3,) the taught direction of travel there (used until a second knot exists).
    min_spacing_mm : knots closer than this along the seam to the last one are not added.
    smoothing_mm : the fit's kernel reaches twice this far either side of the point evaluated, mm.
    """

    def __init__(self, start_mm, start_tangent, min_spacing_mm: float = 0.2, smoothing_mm: float = 5.0):
        t = np.asarray(start_tangent, float)
        self.start_tangent = t / np.linalg.norm(t)
        self.s = [0.0]
        self.p = [np.asarray(start_mm, float)]
        self.min_spacing_mm = min_spacing_mm
        self.smoothing_mm = smoothing_mm
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
        return True

    def arc_of(self, point_mm, tangent) -> float:
        """The arc length a new knot at ``point_mm`` gets: the last knot's plus the step projected on the
        tangent (the straight distance from the start point for the first seen knot)."""
        step = np.asarray(point_mm, float) - self.p[-1]
        return self.s[-1] + (float(step @ tangent) if len(self.s) > 1 else float(np.linalg.norm(step)))

    def fit(self, s_from: float) -> None:
        """Take the knots from ``s_from`` - :data:`BEHIND_MM` on (and the one before) for the evaluations
        that follow (call it after adding knots; ``s_from`` is the torch's progress)."""
        s = np.asarray(self.s)
        keep = np.flatnonzero(s >= s_from - BEHIND_MM)
        first = max(0, keep[0] - 1) if len(keep) else len(s) - 1
        self._knots = (s[first:], np.asarray(self.p[first:]))

    def _local(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) and derivative d/ds (3,) of the local quadratic fit at s (within the knots)."""
        S, P = self._knots
        lo, hi, h = self._window(s)
        if hi - lo < 4:         # too few knots for a smoothed fit: through the nearest ones
            return self._interp(s)
        d = S[lo:hi] - s
        w = np.sqrt((1.0 - np.abs(d / h) ** 3) ** 3)
        A = np.column_stack([np.ones_like(d), d, d * d]) * w[:, None]
        coef = np.linalg.lstsq(A, P[lo:hi] * w[:, None], rcond=None)[0]
        return coef[0], coef[1]

    def _window(self, s: float) -> tuple[int, int, float]:
        """The knots [lo, hi) of the fit at s and its kernel's half width h (mm): 2 ``smoothing_mm``, widened
        so that each side holds half the knots a full window holds at the knots' median spacing (a gap in
        the seam, where the sensor saw nothing, is bridged by the knots beyond it), or the one side holds
        them all at an end of the knots. The last knots never carry the fit alone."""
        S, _ = self._knots
        h = 2.0 * self.smoothing_mm
        if len(S) < 4:
            return 0, len(S), h
        half = max(2, int(round(h / max(float(np.median(np.diff(S))), 1e-9))))
        i = int(np.searchsorted(S, s, side="left"))      # knots [0, i) lie before s, [i, n) from s on
        right = min(len(S) - i, half)                     # half the knots each side, a side short of them
        left = min(i, 2 * half - right)                   # lending its share to the other
        right = min(len(S) - i, 2 * half - left)
        reach = [h, s - S[i - left] if left else 0.0, S[i + right - 1] - s if right else 0.0]
        h = 1.001 * max(reach)
        lo, hi = np.searchsorted(S, [s - h, s + h], side="left")
        return int(lo), int(hi), h

    def _interp(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        S, P = self._knots
        if len(S) == 1:
            return P[0], self.start_tangent
        i = int(np.clip(np.searchsorted(S, s) - 1, 0, len(S) - 2))
        slope = (P[i + 1] - P[i]) / (S[i + 1] - S[i])
        return P[i] + (s - S[i]) * slope, slope

    def position(self, s: float) -> np.ndarray:
        """The seam at arc length s, (3,) mm: the fit within the knots, the end tangent beyond the last
        (bridging), the first knot's fit before the start."""
        S, _ = self._knots
        if s > S[-1]:
            return self._local(S[-1])[0] + (s - S[-1]) * self.tangent(S[-1])
        return self._local(max(s, S[0]))[0]

    def tangent(self, s: float) -> np.ndarray:
        """Unit tangent (3,) at arc length s (clamped to the knots)."""
        S, _ = self._knots
        d = self._local(float(np.clip(s, S[0], S[-1])))[1]
        return d / np.linalg.norm(d)
