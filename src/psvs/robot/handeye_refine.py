"""Hand-eye calibration refined over the images: cam2flange X and the target's pose in the base T that
minimise the reprojection error of the grid's discs in both views of the complex images.

The target is fixed in the base, so in view i its disc k sits at inv(F_i X) T P_k in frame C, and is seen
at that point's exact projection into the left and the right view (:func:`psvs.optics.project.
project_points`: mirrors, plate, lens). The residuals are the detected centres minus those projections,
px; scipy's ``least_squares`` (trust-region reflective, soft-L1 loss at 0.5 px so that a badly detected
disc cannot pull the solution) solves for the 12 pose parameters (rotation vectors and translations),
started from a closed-form X (Park & Martin) and the mean of the views' target poses. This is the
maximum-likelihood solution under equal pixel noise, which the closed form on triangulated poses is not:
triangulated depth is several times noisier than the lateral position, and the closed form's rotation
errors reach the translation through the lever arm of the views' motions.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from psvs._threads import one_blas_thread
from psvs.optics.project import project_points
from psvs.optics.rig import Rig
from psvs.robot.handeye_noise import ResidualNoise, residual_noise
from psvs.transforms import concat, invert_transform, transform_from, transform_from_rotvec

#: Soft-L1 loss scale (px): residuals beyond it count as outliers.
LOSS_SCALE_PX = 0.5
#: Residual (px) of a disc that the optics cannot project (outside a mirror): the solver avoids it.
MISS_PX = 100.0


def _params(A2B: np.ndarray) -> np.ndarray:
    return np.concatenate([Rotation.from_matrix(A2B[:3, :3]).as_rotvec(), A2B[:3, 3]])


def _poses(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return transform_from_rotvec(x[:3], x[3:6]), transform_from_rotvec(x[6:9], x[9:12])


def _residual_function(fits: list, model_mm: np.ndarray, rig: Rig):
    """(residuals(x, F) -> (M,) px, unread (M / 2, 2) bool): the detected centres of ``fits`` minus the
    projections of the discs at cam2flange and target2base ``x`` (12,) through flange poses ``F`` (one (4, 4)
    mm per view); rows of discs not read are 0 (they say nothing) and ``unread``."""
    obs = np.concatenate([np.concatenate([f.left_px for f in fits]), np.concatenate([f.right_px for f in fits])])
    unread = np.isnan(obs)

    def residuals(x: np.ndarray, F: list) -> np.ndarray:
        X, T = _poses(x)
        pts = np.concatenate([model_mm @ t2c[:3, :3].T + t2c[:3, 3]
                              for t2c in (concat(T, invert_transform(concat(X, Fi))) for Fi in F)])
        out = []
        for view in ("left", "right"):
            uv, ok = project_points(pts, rig, view)
            uv[~ok] = np.nan
            out.append(uv)
        r = np.concatenate(out) - obs
        r[~np.isfinite(r)] = MISS_PX
        r[unread] = 0.0                             # a disc not read in a view says nothing
        return r.ravel()
    return residuals, unread


@one_blas_thread()     # the same numbers on any core count
def refine_hand_eye(flange2base: list[np.ndarray], fits: list, model_mm: np.ndarray, rig: Rig,
                    cam2flange: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Refine cam2flange (4, 4) mm over the discs' reprojection error (see the module docstring).

    Parameters
    ----------
    flange2base : list of (4, 4) mm, one per view.
    fits : list of :class:`psvs.robot.handeye.TargetFit`, one per view: the detected centres (n, 2) px in
        each view, row k the target's disc k (NaN: not read, left out), and the view's target2cam (4, 4) mm.
    model_mm : (n, 3) the discs' centres in the target's frame, mm.
    rig : the rig the images are seen through (what the sensor knows of it).
    cam2flange : (4, 4) the closed-form start.

    Returns
    -------
    (cam2flange (4, 4), target2base (4, 4), reprojection RMS px over both views)
    """
    F = [np.asarray(f, dtype=np.float64) for f in flange2base]
    targets = [concat(f.target2cam, cam2flange, Fi) for f, Fi in zip(fits, F, strict=True)]
    start = transform_from(targets[0][:3, :3], np.mean([T[:3, 3] for T in targets], axis=0))
    residuals, unread = _residual_function(fits, model_mm, rig)
    x0 = np.concatenate([_params(cam2flange), _params(start)])
    sol = least_squares(residuals, x0, args=(F,), method="trf", loss="soft_l1", f_scale=LOSS_SCALE_PX, x_scale="jac")
    X, T = _poses(sol.x)
    return X, T, float(np.sqrt(np.mean(residuals(sol.x, F)[~unread.ravel()] ** 2)))


@one_blas_thread()
def fit_noise(flange2base: list[np.ndarray], fits: list, model_mm: np.ndarray, rig: Rig, cam2flange: np.ndarray,
              target2base: np.ndarray, edge_px: float, accuracy_mm: float) -> ResidualNoise:
    """What the detector's noise (``edge_px`` on each coordinate) and the robot's positioning accuracy
    (``accuracy_mm``) alone give at the solution (cam2flange, target2base) of :func:`refine_hand_eye` with
    the same inputs: the reprojection RMS expected and its 1 % level, and the mount's 1-sigma
    (:mod:`psvs.robot.handeye_noise`)."""
    residuals, unread = _residual_function(fits, model_mm, rig)
    x = np.concatenate([_params(cam2flange), _params(target2base)])
    return residual_noise(residuals, x, flange2base, ~unread.ravel(), edge_px, accuracy_mm)
