"""What the hand-eye fit's residual and its mount would be from its inputs' noise alone.

At the solution x* of :func:`psvs.robot.handeye_refine.refine_hand_eye` (cam2flange X and target2base T,
12 parameters) the residual r of M read disc coordinates is, to first order, r = P e: the noise e of the
inputs less what the 12 parameters absorb (P = I - J (J'J)^-1 J', J = dr/dx, M x 12). Its noise:

- the detector's, sigma_d px on each coordinate, independent;
- the robot's, on each view's flange pose: a position error of RMS ``accuracy_mm`` (ISO 9283 positioning
  accuracy; accuracy / sqrt(3) on each axis) and an orientation error of accuracy / :data:`LEVER_MM` rad (the
  position accuracy over an arm's reach) about the flange's own origin (:func:`perturbed`), shared by every
  disc of the view: e_robot = G w, G = dr/d(flange
  pose) (M x 6 V), w of covariance C.

So E|r|^2 = tr(P S) with S = sigma_d^2 I + G C G', and for Gaussian noise |r|^2 is close to g chi2(h) with
g = tr((PS)^2) / tr(PS), h = tr(PS)^2 / tr((PS)^2) (Welch and Satterthwaite). Every trace comes from the
small matrix K = G' P G (6 V x 6 V): tr(PS) = sigma_d^2 (M - 12) + tr(C K), tr((PS)^2) = sigma_d^4 (M - 12)
+ 2 sigma_d^2 tr(C K) + |C^1/2 K C^1/2|^2. The fit is refused when its RMS exceeds the level that noise alone
exceeds 1 % of the time (:data:`ALPHA`). The same algebra gives the parameters' covariance,
(J'J)^-1 J' S J (J'J)^-1: the mount's stated uncertainty.

Independent check: tests/robot/test_handeye_noise.py draws the noise, refits and compares.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from psvs.transforms import matrix_from_rotvec, transform_from

#: mm: the reach over which an arm's position accuracy becomes its orientation accuracy (rad = mm / lever).
LEVER_MM = 500.0
#: The chance that a fit whose inputs are as noisy as stated is refused.
ALPHA = 0.01
#: Finite-difference steps of the Jacobians: rad for rotation vectors, mm for translations.
_STEP_RAD, _STEP_MM = 1e-6, 1e-4


@dataclass(frozen=True)
class ResidualNoise:
    """What noise alone gives at a hand-eye solution: the expected reprojection RMS ``expected_px`` and the
    level ``limit_px`` it exceeds with probability :data:`ALPHA`; the mount's 1-sigma position
    ``mount_sigma_mm`` (RMS over the axes of its translation's standard deviations) and orientation
    ``mount_sigma_rad``."""

    expected_px: float
    limit_px: float
    mount_sigma_mm: float
    mount_sigma_rad: float


def perturbed(flange2base: np.ndarray, d: np.ndarray) -> np.ndarray:
    """A flange pose (4, 4) mm with a robot's error ``d`` (6,): turned by the rotation vector d[:3] (rad, base
    axes) about the flange's own origin, and moved by d[3:] (mm, base axes)."""
    F = np.asarray(flange2base, dtype=np.float64)
    return transform_from(matrix_from_rotvec(d[:3]) @ F[:3, :3], F[:3, 3] + d[3:])


def _jacobian(f, x: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Central differences of f (R^n -> R^M) at x: (M, n)."""
    cols = []
    for k, h in enumerate(steps):
        dx = np.zeros_like(x)
        dx[k] = h
        cols.append((f(x + dx) - f(x - dx)) / (2 * h))
    return np.column_stack(cols)


def residual_noise(residuals, x: np.ndarray, flange2base: list, read: np.ndarray, edge_px: float,
                   accuracy_mm: float) -> ResidualNoise:
    """The module docstring's figures at solution ``x`` (12,) of ``residuals(x, F)`` (the hand-eye residual
    function of :func:`psvs.robot.handeye_refine.fit_noise`, flange poses ``F``: (4, 4) mm each),
    ``read`` (M,) bool the rows of read discs, ``edge_px`` the detector's noise on each coordinate (px) and
    ``accuracy_mm`` the robot's positioning accuracy (mm, RMS)."""
    F = [np.asarray(f, dtype=np.float64) for f in flange2base]
    steps = np.array([_STEP_RAD] * 3 + [_STEP_MM] * 3)
    J = _jacobian(lambda y: residuals(y, F), x, np.tile(steps, 2))[read]
    cols = []
    for i in range(len(F)):        # each view's flange pose, turned about its own origin and moved, base axes

        def moved(d, i=i):
            return residuals(x, [perturbed(Fi, d) if k == i else Fi for k, Fi in enumerate(F)])
        cols.append(_jacobian(moved, np.zeros(6), steps)[read])
    G = np.hstack(cols)
    m, n = J.shape
    q, rr = np.linalg.qr(J)
    PG = G - q @ (q.T @ G)
    c = np.tile([accuracy_mm / LEVER_MM] * 3 + [accuracy_mm] * 3, len(F)) / math.sqrt(3.0)   # each axis's sigma
    S = c[:, None] * (G.T @ PG) * c[None, :]
    s2 = edge_px ** 2
    tr = s2 * (m - n) + np.trace(S)
    tr2 = s2 ** 2 * (m - n) + 2 * s2 * np.trace(S) + float(np.sum(S * S))
    g, h = tr2 / tr, tr ** 2 / tr2
    # the parameters' covariance (J'J)^-1 J' (s2 I + G C G') J (J'J)^-1, through J = q rr
    rinv = np.linalg.inv(rr)
    JG = J.T @ G * c[None, :]
    jtj_inv = rinv @ rinv.T
    cov = s2 * jtj_inv + jtj_inv @ JG @ JG.T @ jtj_inv
    var = np.diag(cov)
    return ResidualNoise(math.sqrt(tr / m), math.sqrt(g * chi2.ppf(1 - ALPHA, h) / m),
                         math.sqrt(float(np.mean(var[3:6]))), math.sqrt(float(np.mean(var[:3]))))
