"""Mirror length in the plane of the optical axis: the paper's eqs. (1)-(8) (section III.1, Fig. 3).

A mirror crosses the axis at B, at distance OB from the optical centre O, at angle omega_1 to the axis;
the field is the wedge of half-angle a about the axis. A and C are where the wedge's edge rays meet the
mirror (A on the far side, C on the near side); D is the foot of C's perpendicular on the axis.
All lengths in mm, angles in rad; inputs may be floats or broadcastable arrays.
"""
from __future__ import annotations

import numpy as np


def _check(ob, a, w):
    ob, a, w = (np.asarray(v, dtype=float) for v in (ob, a, w))
    if np.any(ob <= 0):
        raise ValueError(f"OB must be > 0 mm, got {ob}")
    if np.any((a <= 0) | (a >= np.pi / 2)):
        raise ValueError(f"half field angle a must be in (0, pi/2) rad, got {a}")
    if np.any((w <= 0) | (w > np.pi / 2)):
        raise ValueError(f"omega_1 must be in (0, pi/2] rad, got {w}")
    if np.any(w <= a):
        raise ValueError(f"omega_1 must exceed the half field angle a, or the far edge ray never meets the "
                         f"mirror; got omega_1={w}, a={a}")
    return ob, a, w


def ab_eq1(ob, a, w):
    """Eq. (1): AB = OB tan a cos w / tan(w - a) + OB tan a sin w (far side of the mirror), mm."""
    ob, a, w = _check(ob, a, w)
    return ob * np.tan(a) * np.cos(w) / np.tan(w - a) + ob * np.tan(a) * np.sin(w)


def segments_eq2_4(ob, a, w):
    """Eqs. (2)-(4) solved with OB = OD + DB: returns (CD, BC, OD, DB), mm.

    BC = CD / sin w (2), OD = CD / tan a (3), DB = BC cos w (4).
    """
    ob, a, w = _check(ob, a, w)
    cd = ob / (1.0 / np.tan(a) + np.cos(w) / np.sin(w))
    bc = cd / np.sin(w)
    return cd, bc, cd / np.tan(a), bc * np.cos(w)


def bc_eq5(ob, a, w):
    """Eq. (5): BC = OB tan a / (sin w + cos w tan a) (near side of the mirror), mm."""
    ob, a, w = _check(ob, a, w)
    return ob * np.tan(a) / (np.sin(w) + np.cos(w) * np.tan(a))


def mirror_length_eq6(ob, a, w):
    """Eq. (6): AC = AB + BC, the mirror length that covers the field wedge, mm.

    Examples
    --------
    >>> round(float(mirror_length_eq6(25.0, np.radians(10), np.radians(45))), 9)
    12.86829104
    """
    return ab_eq1(ob, a, w) + bc_eq5(ob, a, w)


def mirror_length_eq7(ob, a):
    """Eq. (7), omega_1 = 45 deg: AC = sqrt(2) OB tan 2a, mm."""
    ob, a, _ = _check(ob, a, np.pi / 4)
    return np.sqrt(2.0) * ob * np.tan(2 * a)


def mirror_length_eq8(ob, a):
    """Eq. (8), omega_1 = 90 deg: AC = 2 OB tan a, mm."""
    ob, a, _ = _check(ob, a, np.pi / 2)
    return 2.0 * ob * np.tan(a)
