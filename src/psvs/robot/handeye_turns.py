"""Whether the target's turn seen in each view agrees with the flange's turn, within the inputs' noise.

The target is fixed in the base, so its orientation F_k X C_k (flange2base F_k, cam2flange X, the view's
target2cam C_k from its discs triangulated through the rig, :class:`psvs.robot.handeye.TargetFit`) is one
and the same rotation T in every view k. The hand-eye fit itself (:mod:`psvs.robot.handeye_refine`) weighs
the discs' pixels, where a rig whose depth is scaled wrongly hides: a focal length 6 % long in the rig file
moves every view's pixels by 0.13 px RMS (0.04 px with the right one), well inside what a 0.5 mm robot
accuracy leaves (0.94 px), yet it stretches each view's triangulated card in depth and turns its plane by up
to 2 deg, and the mount comes out 21 mm off at a stated 1-sigma of 1.45 mm (an adversarial trial, 2026-12-05). The
turns tell.

**The test.** Linearised at the fit's X and the views' mean orientation, each view's misfit
d_k = log(F_k X C_k T') (a rotation vector, base axes) is d_k = A_k e - t + n_k with A_k the rotation of
F_k X, e a small turn of X (flange axes) and t one of T (base axes): both are fitted (6 unknowns, weighted
least squares). The noise n_k has two parts:

- the robot's: each flange pose turned by accuracy / :data:`~psvs.robot.handeye_noise.LEVER_MM` rad RMS
  (accuracy / lever / sqrt(3) on each axis, as :mod:`psvs.robot.handeye_noise` has it);
- the view's own fit: the rigid fit of the grid's model to its triangulated discs (Kabsch) turns by
  H^-1 (sum_i [a_i]x' S [a_i]x) H^-1, H = sum_i [a_i]x' [a_i]x, a_i the model's points about their centroid
  turned into the camera, S the 3 x 3 covariance of the triangulated discs (camera axes, the depth's larger
  share included), pooled over the views' fit residuals (:func:`pooled_noise`): measured, not assumed.

The weighted sum of squares then follows chi-square with 3 V - 6 degrees of freedom (V views); a fit beyond
its 1 - :data:`ALPHA` quantile is refused (:func:`check_turns`). Independent check:
tests/robot/test_handeye_turns.py draws orientation noise as stated and compares the statistic's false alarms.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from psvs.errors import MeasurementError
from psvs.robot.handeye_noise import LEVER_MM

#: The chance that views whose turns agree with the flange's within the stated noise are refused.
ALPHA = 0.01


@dataclass(frozen=True)
class TurnAgreement:
    """The views' turns against the flange's: ``statistic`` (the weighted sum of squares, module docstring),
    its degrees of freedom ``dof``, the level ``limit`` noise alone exceeds with probability :data:`ALPHA`,
    and the RMS misfit ``rms_deg`` against the ``expected_deg`` noise gives (over the views, per axis)."""

    statistic: float
    dof: int
    limit: float
    rms_deg: float
    expected_deg: float


def _cross(a: np.ndarray) -> np.ndarray:
    """[a]x for each row of a (n, 3): (n, 3, 3)."""
    z = np.zeros(len(a))
    return np.stack([np.stack([z, -a[:, 2], a[:, 1]], -1), np.stack([a[:, 2], z, -a[:, 0]], -1),
                     np.stack([-a[:, 1], a[:, 0], z], -1)], axis=1)


def fit_residuals(model_mm: np.ndarray, points_mm: np.ndarray, target2cam: np.ndarray) -> np.ndarray:
    """The residuals (n, 3, mm, camera axes) of one view's rigid fit ``target2cam`` (4, 4) of the grid's model
    ``model_mm`` (n, 3, target frame) to its triangulated discs ``points_mm`` (n, 3; NaN rows, not read, left
    out)."""
    ok = np.all(np.isfinite(points_mm), axis=1)
    R, t = target2cam[:3, :3], target2cam[:3, 3]
    return points_mm[ok] - (model_mm[ok] @ R.T + t)


def pooled_noise(fits: list, model_mm: np.ndarray) -> np.ndarray:
    """The 3 x 3 covariance (mm^2, camera axes) of the discs' triangulated positions, pooled over the views'
    rigid fits (:class:`psvs.robot.handeye.TargetFit` each): their residuals' sum of outer products over the
    3 n - 6 degrees of freedom each view leaves (n / (n - 2) of its n discs' mean). One covariance for the
    session: each view's 20-35 discs alone estimate it so loosely that the test would refuse a few times
    more often than it states."""
    total, dof = np.zeros((3, 3)), 0.0
    for f in fits:
        r = fit_residuals(model_mm, f.points_mm, f.target2cam)
        total += r.T @ r
        dof += max(len(r) - 2.0, 0.0)
    return total / dof if dof > 0 else np.full((3, 3), np.inf)


def fit_turn_covariance(model_mm: np.ndarray, points_mm: np.ndarray, target2cam: np.ndarray,
                        noise_mm2: np.ndarray | None = None) -> np.ndarray:
    """The covariance (3, 3, rad^2, camera axes) of the turn of one view's rigid fit ``target2cam`` (4, 4) of
    the grid's model ``model_mm`` (n, 3, target frame) to its triangulated discs ``points_mm`` (n, 3, camera
    frame; NaN rows: not read): the module docstring's sandwich, with the points' noise covariance
    ``noise_mm2`` (3, 3, mm^2, camera axes; None: this view's own residuals', n / (n - 2) times their mean
    outer product)."""
    ok = np.all(np.isfinite(points_mm), axis=1)
    p = model_mm[ok]
    n = len(p)
    if n < 4:
        return np.full((3, 3), np.inf)
    if noise_mm2 is None:
        r = fit_residuals(model_mm, points_mm, target2cam)
        noise_mm2 = (r.T @ r) / (n - 2.0)
    a = (p - p.mean(axis=0)) @ target2cam[:3, :3].T
    X = _cross(a)                                   # (n, 3, 3)
    H = np.einsum("nji,njk->ik", X, X)
    M = np.einsum("nji,jl,nlk->ik", X, noise_mm2, X)
    Hi = np.linalg.inv(H)
    return Hi @ M @ Hi


def turn_agreement(fits: list, flange2base: list[np.ndarray], cam2flange: np.ndarray, model_mm: np.ndarray,
                   robot_accuracy_mm: float) -> TurnAgreement:
    """The module docstring's test of the views ``fits`` (:class:`psvs.robot.handeye.TargetFit`, one per flange
    pose ``flange2base`` (4, 4) mm) at the hand-eye solution ``cam2flange`` (4, 4), the grid's model
    ``model_mm`` (n, 3) and the robot's stated accuracy (mm)."""
    X = np.asarray(cam2flange, dtype=np.float64)
    A = [np.asarray(F, dtype=np.float64)[:3, :3] @ X[:3, :3] for F in flange2base]
    R = [a @ f.target2cam[:3, :3] for a, f in zip(A, fits, strict=True)]
    robot = (robot_accuracy_mm / LEVER_MM) ** 2 / 3.0 * np.eye(3)
    noise = pooled_noise(fits, model_mm)
    C = [a @ fit_turn_covariance(model_mm, f.points_mm, f.target2cam, noise) @ a.T + robot
         for a, f in zip(A, fits, strict=True)]
    T = Rotation.from_matrix(np.array(R)).mean().as_matrix()
    d = np.array([Rotation.from_matrix(r @ T.T).as_rotvec() for r in R])     # base axes
    W = [np.linalg.cholesky(np.linalg.inv(c)).T for c in C]                 # whitening: W' W = C^-1
    J = np.vstack([w @ np.hstack([a, -np.eye(3)]) for w, a in zip(W, A, strict=True)])
    y = np.concatenate([-(w @ dk) for w, dk in zip(W, d, strict=True)])
    x = np.linalg.lstsq(J, y, rcond=None)[0]
    res = J @ x - y                                                          # whitened misfits
    raw = np.array([np.linalg.solve(w, m) for w, m in zip(W, res.reshape(-1, 3), strict=True)])   # rad
    dof = 3 * len(R) - 6
    expected = math.sqrt(np.mean([np.trace(c) / 3.0 for c in C]) * dof / (3 * len(R)))
    return TurnAgreement(float(res @ res), dof, float(chi2.ppf(1.0 - ALPHA, dof)),
                         math.degrees(math.sqrt(float(np.mean(raw ** 2)))), math.degrees(expected))


def check_turns(agreement: TurnAgreement, robot_accuracy_mm: float) -> None:
    """MeasurementError when the views' turns disagree with the flange's beyond the level noise exceeds
    :data:`ALPHA` of the time (:func:`turn_agreement`)."""
    a = agreement
    if not (math.isfinite(a.statistic) and a.statistic <= a.limit):
        raise MeasurementError(
            f"the target's turn in the views disagrees with the flange's: {a.rms_deg:.3g} deg RMS against the "
            f"{a.expected_deg:.3g} deg that the views' own fits and a {robot_accuracy_mm:g} mm robot accuracy "
            f"explain (chi-square {a.statistic:.1f} on {a.dof} degrees of freedom, limit {a.limit:.1f}, exceeded by "
            "that noise 1 % of the time): the rig file's depth is off (its focal length, baseline or plate: "
            "calibrate the rig first), or the poses are not the images' poses")
