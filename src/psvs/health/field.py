"""The smooth field a moved mirror makes on the twins' rows, and its fit to the tiles (psvs.health.check).

A turn of one view moves its rows by a quadratic over the grid (:func:`curvature_bound_px`); the field is the
quadratic :func:`field_basis` with its curvature held to what a turned view can make, fitted robustly to the
tiles' row offsets (:func:`robust_fit`).
"""
from __future__ import annotations

import math

import numpy as np

from psvs.health.rows import FAR_REACH_DEG

#: Tiles farther than this many robust sigmas (and 0.5 px) from the fitted field are left out of it.
OUTLIER_SIGMAS = 3.0
#: A tile whose leverage on the fitted field exceeds this pins a term of it alone: the others cannot check it.
MAX_LEVERAGE = 0.97
#: The largest turn of a view whose field the check fits (deg): twice the farthest it searches the rows
#: (psvs.health.rows.FAR_REACH_DEG), a margin for turns about the other axes. It bounds the field's curvature
#: (:func:`curvature_bound_px`).
MAX_TURN_DEG = 2.0 * FAR_REACH_DEG
#: The u^2 term's bound as a share of the u v term's: nil for a turn, the plate's refraction gives it a little
#: (drawn rigs, a mirror turned up to 0.5 deg about both axes: at most 0.085 of tan(0.5 deg) (W'/2)(H'/2) / f).
U2_SHARE = 0.1


def field_basis(centre_px: np.ndarray, grid_shape: tuple[int, int]) -> np.ndarray:
    """The field's basis (n, 6) at points (n, 2) of a grid (H', W'): 1, x, y, x^2, x y, y^2 with x, y the
    points scaled to -1..1 over the grid."""
    h, w = grid_shape
    x = 2.0 * centre_px[:, 0] / max(w - 1, 1) - 1.0
    y = 2.0 * centre_px[:, 1] / max(h - 1, 1) - 1.0
    return np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])


def curvature_bound_px(grid_shape: tuple[int, int], focal_px: float | None) -> np.ndarray:
    """Bounds (6,) on the field's coefficients (:func:`field_basis`, px) that a view turned by up to
    :data:`MAX_TURN_DEG` can make on a grid (H', W') of focal length ``focal_px`` (px). A turn (w_x, w_y, w_z)
    of one view moves its rows by f w_x + w_z u + (w_x v^2 + w_y u v) / f (u, v px from the grid's centre): the
    constant and linear terms are free (inf), the u v term at most t (W'/2)(H'/2) / f and the v^2 term
    t (H'/2)^2 / f (t = tan(turn)), the u^2 term nil but for the plate's refraction (:data:`U2_SHARE` of the
    u v term's bound). Drawn rigs, a mirror turned up to 0.5 deg about both axes: u v and v^2 up to 1.4 times
    tan(0.5 deg) (W'/2)(H'/2) / f (a mirror turns its view by twice its own turn). A field bent further (wrong
    tiles at the ends of a few rows, the field passing through them: an undrifted build's seam plates, 15
    tiles, u^2 -17 px and u v 27 px, read as a drift of 2.05 px) is no moved mirror's. ``focal_px`` None: all
    free."""
    h, w = grid_shape
    bound = np.full(6, np.inf)
    if focal_px is not None and math.isfinite(focal_px) and focal_px > 0:
        t, hu, hv = math.tan(math.radians(MAX_TURN_DEG)), 0.5 * (w - 1), 0.5 * (h - 1)
        bound[3:] = [U2_SHARE * t * hu * hv / focal_px, t * hu * hv / focal_px, t * hv * hv / focal_px]
    return bound


def robust_fit(A: np.ndarray, y: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(coefficients, inliers, robust sigma px) of the field, its coefficients within +-``bound`` (6,)
    (:func:`curvature_bound_px`): soft-L1 least squares, then least squares on the tiles within
    :data:`OUTLIER_SIGMAS` robust sigmas (and 0.5 px) of it. Then each tile is judged by what the others predict of
    it, one at a time: on few tiles a quadratic bends to pass near a wrong tile far out, which its own residual does
    not show. A tile the others cannot predict (leverage above :data:`MAX_LEVERAGE`: it alone pins a term of the
    field) is left out, its evidence unchecked; the tile whose externally studentized residual (its residual over
    the fit's noise without it and sqrt(1 - its leverage)) is largest is left out while it exceeds Student's t at a
    5 % family-wise level (Bonferroni over the tiles) and stands 0.5 px or more off the others' prediction."""
    from scipy.optimize import least_squares
    from scipy.special import stdtrit
    p = A.shape[1]
    c = least_squares(lambda q: A @ q - y, np.zeros(p), loss="soft_l1", f_scale=0.3, bounds=(-bound, bound)).x
    fit = lambda on: bounded_lstsq(A[on], y[on], bound)  # noqa: E731
    inliers = np.ones(len(y), bool)
    for _ in range(3):
        r = y - A @ c
        sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
        keep = np.abs(r) <= max(OUTLIER_SIGMAS * sigma, 0.5)
        if keep.sum() < p + 2:
            break
        inliers = keep
        c = fit(inliers)
    while inliers.sum() > p + 2:
        idx = np.flatnonzero(inliers)
        h = np.einsum("ij,jk,ik->i", A[idx], np.linalg.pinv(A[idx].T @ A[idx]), A[idx])
        r = y[idx] - A[idx] @ c
        if (h > MAX_LEVERAGE).any():
            inliers[idx[h > MAX_LEVERAGE]] = False
        else:
            dof = len(idx) - p - 1
            gone = r ** 2 / np.maximum(1.0 - h, 1e-12)                 # each tile's share of the squared residuals
            s2 = np.maximum((float(np.sum(r ** 2)) - gone) / dof, 1e-12)
            t = np.abs(r) / np.sqrt(s2 * (1.0 - h))
            bad = (t > float(stdtrit(dof, 1.0 - 0.025 / len(idx)))) & (np.abs(r) / (1.0 - h) >= 0.5)
            if not bad.any():
                break
            inliers[idx[np.argmax(np.where(bad, t, 0.0))]] = False
        c = fit(inliers)
    r = y - A @ c
    dof = max(int(inliers.sum()) - p, 1)
    return c, inliers, float(np.sqrt(np.sum(r[inliers] ** 2) / dof))


def bounded_lstsq(A: np.ndarray, y: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Least squares of A (n, p) x = y (n,) with |x| <= ``bound`` (p,): NumPy's when that is within the bounds,
    else SciPy's bounded-variable least squares."""
    c = np.linalg.lstsq(A, y, rcond=None)[0]
    if np.all(np.abs(c) <= bound):
        return c
    from scipy.optimize import lsq_linear
    return lsq_linear(A, y, bounds=(-bound, bound), method="bvls").x
