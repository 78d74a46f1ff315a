"""An independent PSVS ray model for tests (omega_1 = 45 deg only), sharing no code with psvs.optics.

Right view: O reflected in M1 (x - z = -c1) then M4 (x - z = b/2 - c1) is O2 = (b/2, 0, -b/2), and two
parallel mirrors keep directions, so the right view is a pinhole at O2 (paper eqs. 9-10).
Left view: the camera ray i crosses the plate (normal N = (-1, 0, 1)/sqrt 2 along the light) and leaves
it parallel to i, displaced by the textbook amount delta = d sin(theta - theta_t) / cos theta_t toward
the component of N perpendicular to i; M2 and M3 then translate the line by O -> O1 = (-b/2, 0, -b/2).
Projection solves for the pixel with scipy's fsolve (the library iterates a fixed point instead).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import fsolve


class ReferenceRig:
    def __init__(self, f=11.3, pitch=(0.01, 0.01), centre=(319.5, 239.5), b=100.0, d=3.0, n=1.52):
        self.f, self.pitch, self.centre, self.b, self.d, self.n = f, pitch, centre, b, d, n

    def direction(self, u, v):
        x = (u - self.centre[0]) * self.pitch[0]
        y = (v - self.centre[1]) * self.pitch[1]
        i = np.array([x, y, self.f])
        return i / np.linalg.norm(i)

    def pixel(self, vec):
        return (self.centre[0] + self.f * vec[0] / vec[2] / self.pitch[0],
                self.centre[1] + self.f * vec[1] / vec[2] / self.pitch[1])

    def left_line(self, u, v):
        """(point, direction) of the left view's emergent ray for pixel (u, v)."""
        i = self.direction(u, v)
        N = np.array([-1.0, 0.0, 1.0]) / math.sqrt(2)
        cos_th = float(i @ N)
        th = math.acos(cos_th)
        th_t = math.asin(math.sin(th) / self.n)
        delta = self.d * math.sin(th - th_t) / math.cos(th_t)
        perp = N - cos_th * i
        e = perp / np.linalg.norm(perp)
        o1 = np.array([-self.b / 2, 0.0, -self.b / 2])
        return o1 + delta * e, i

    def right_line(self, u, v):
        return np.array([self.b / 2, 0.0, -self.b / 2]), self.direction(u, v)

    def project_right(self, P):
        return self.pixel(np.asarray(P, float) - np.array([self.b / 2, 0.0, -self.b / 2]))

    def project_left(self, P):
        P = np.asarray(P, float)

        def residual(uv):
            o, _ = self.left_line(*uv)
            return np.subtract(self.pixel(P - o), uv)

        guess = self.pixel(P - np.array([-self.b / 2, 0.0, -self.b / 2]))
        uv, info, ok, msg = fsolve(residual, guess, xtol=1e-14, full_output=True)
        assert ok == 1, msg
        return tuple(uv)
