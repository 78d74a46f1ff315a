"""The paper's stereo equations (9)-(17), one function each, on sensor coordinates.

All inputs are arrays of equal shape (any shape; scalars allowed): sensor coordinates x_l, x_r, y_r
in mm (x = (u - cx) pitch_x), focal length f and baseline b in mm. The paper places both virtual
centres at z = -b/2 (omega_1 = 45 deg); for another omega_1 they sit at z_v = -(b/2) tan omega_1, so
every function takes ``z_v`` (default -b/2) and the paper's "z + b/2" reads "z - z_v".
A disparity x_l - x_r <= 0 (or NaN) has no point in front of the rig and gives NaN.
"""
from __future__ import annotations

import numpy as np


def _disparity(xl, xr):
    disp = np.asarray(np.asarray(xl, dtype=float) - np.asarray(xr, dtype=float))
    with np.errstate(invalid="ignore"):
        disp[~(disp > 0)] = np.nan
    return disp


def _zv(b, z_v):
    return -0.5 * np.asarray(b, dtype=float) if z_v is None else z_v


def project_eq9_10(points_mm, f, b, z_v=None):
    """Eqs. (9)-(10): ideal pinhole projections (x_l, x_r, y), mm, of points (N, 3) mm.

    x_r = f (x - b/2) / (z - z_v), x_l = f (x + b/2) / (z - z_v), y_l = y_r = f y / (z - z_v).

    Examples
    --------
    >>> project_eq9_10(np.array([[0.0, 0.0, 1080.0]]), 11.3, 100.0)
    (array([0.5]), array([-0.5]), array([0.]))
    """
    p = np.asarray(points_mm, dtype=float)
    depth = p[..., 2] - _zv(b, z_v)
    return f * (p[..., 0] + b / 2) / depth, f * (p[..., 0] - b / 2) / depth, f * p[..., 1] / depth


def x_eq11(xl, xr, b):
    """Eq. (11): x = (b/2) (x_l + x_r) / (x_l - x_r), mm."""
    return 0.5 * b * (np.asarray(xl, dtype=float) + xr) / _disparity(xl, xr)


def z_eq12(xl, xr, f, b, z_v=None):
    """Eq. (12): z = b f / (x_l - x_r) - b/2, mm (no plate correction).

    Examples
    --------
    >>> float(z_eq12(0.5, -0.5, 11.3, 100.0))
    1080.0
    """
    z = np.divide(b * f, _disparity(xl, xr))
    z += _zv(b, z_v)
    return z


def x_eq13(xr, z, f, b, z_v=None):
    """Eq. (13) = eq. (16): x = (x_r / f) (z + b/2) + b/2, mm, from the right view (no plate on its path)."""
    x = np.asarray(z - _zv(b, z_v), dtype=float)
    x *= xr
    x /= f
    x += 0.5 * b
    return x


def y_eq14(yr, z, f, b, z_v=None):
    """Eq. (14) = eq. (17): y = (y_r / f) (z + b/2), mm."""
    y = np.asarray(z - _zv(b, z_v), dtype=float)
    y *= yr
    y /= f
    return y


def z_eq15(xl, xr, f, b, l_mm, m_mm, z_v=None):
    """Eq. (15): z = b f / (x_l - x_r) - b/2 + x_l l / (x_l - x_r) + f m / (x_l - x_r), mm.

    l and m (mm) carry the M1 plate's refraction (:mod:`psvs.optics.plate`); l = m = 0 is eq. (12).
    """
    z = np.asarray(np.asarray(xl, dtype=float) * l_mm)
    z += b * f + f * m_mm
    z /= _disparity(xl, xr)
    z += _zv(b, z_v)
    return z
