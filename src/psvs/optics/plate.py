"""The M1 glass plate: lateral ray shift and the refraction terms l, m of eq. (15).

Derivation (docs/optics.md has it in full). A ray leaving O at angle alpha from the axis in the XZ plane
meets the plate at incidence theta = pi/2 - omega_1 + alpha. A parallel plate of thickness d and index n
keeps the direction and shifts the ray sideways, perpendicular to itself and toward -X, by

    delta(theta) = d (sin theta - cos theta tan theta_t),   sin theta_t = sin theta / n.

M2 and M3 are parallel, so they only translate that ray: the left ray leaves the rig as if from
O1 + delta (-cos alpha, 0, sin alpha), whose X offset on the plane z = z_v of the virtual centres is
s = -delta / cos alpha. Intersecting it with the right ray gives z - z_v = f (b - s) / (x_l - x_r):
eq. (15) is exactly this with -f s linearised in x_l, -f s = x_l l + f m, so to first order about
alpha = 0 (x_l = f tan alpha):

    m = delta(theta_0),   l = d delta / d theta (theta_0),   theta_0 = pi/2 - omega_1,
    d delta / d theta = d (cos theta + sin theta tan theta_t - cos^2 theta / (n cos^3 theta_t)).
"""
from __future__ import annotations

import math

import numpy as np

from psvs.optics.rig import Rig


def plate_shift_mm(incidence_rad, thickness_mm: float, refractive_index: float):
    """Lateral displacement delta of a ray crossing a parallel plate (the classic plate formula).

    Parameters
    ----------
    incidence_rad : float or ndarray
        Angle of incidence theta to the plate normal, rad.
    thickness_mm : float
        d, mm.
    refractive_index : float
        n of the glass (air outside).

    Returns
    -------
    delta_mm : float or ndarray
        Perpendicular distance between the incident line and the emergent ray, mm.

    Examples
    --------
    >>> round(float(plate_shift_mm(math.pi / 4, 3.0, 1.52)), 6)   # the default plate on the axis
    1.006502
    """
    th = np.asarray(incidence_rad, dtype=float)
    sin_t = np.sin(th) / refractive_index
    tan_t = sin_t / np.sqrt(1.0 - sin_t * sin_t)
    return thickness_mm * (np.sin(th) - np.cos(th) * tan_t)


def plate_shift_derivative_mm(incidence_rad, thickness_mm: float, refractive_index: float):
    """d delta / d theta of :func:`plate_shift_mm`, mm per rad (same shapes)."""
    th = np.asarray(incidence_rad, dtype=float)
    n = refractive_index
    sin_t = np.sin(th) / n
    cos_t = np.sqrt(1.0 - sin_t * sin_t)
    return thickness_mm * (np.cos(th) + np.sin(th) * sin_t / cos_t - np.cos(th) ** 2 / (n * cos_t**3))


def derived_refraction_terms(rig: Rig) -> tuple[float, float]:
    """l and m of eq. (15), mm, derived from d, n and omega_1 (first order about the optical axis).

    Examples
    --------
    >>> from psvs import default_rig
    >>> [round(v, 4) for v in derived_refraction_terms(default_rig())]
    [1.8134, 1.0065]
    """
    m = rig.mirrors
    theta0 = math.pi / 2 - m.angle_rad
    l_mm = float(plate_shift_derivative_mm(theta0, m.plate_thickness_mm, m.refractive_index))
    m_mm = float(plate_shift_mm(theta0, m.plate_thickness_mm, m.refractive_index))
    return l_mm, m_mm


#: What the glass a rig file describes may really be, for the range of l and m a fit may answer
#: (:func:`plausible_refraction_terms`): its thickness within -20 % and +25 % of the file's (a plate of
#: 3 mm ordered is 3 +- 0.2 mm; a 2.5 or 4 mm plate needs its own file), any optical glass (n 1.45-1.95),
#: omega_1 within 3 deg of the file's. The paper's fit on its build moved l and m by 8 and 2 % from
#: their derived values (examples/known_points.csv: 1.96 and 1.02 mm against 1.81 and 1.01).
PLAUSIBLE_PLATE = {"thickness_factor": (0.8, 1.25), "refractive_index": (1.45, 1.95), "angle_deg": 3.0}


def plausible_refraction_terms(rig: Rig) -> tuple[tuple[float, float], tuple[float, float]]:
    """The (low, high) of l and of m of eq. (15), mm, that a plate of the rig's kind can give
    (:data:`PLAUSIBLE_PLATE` about its file's d, n and omega_1; first order about the optical axis, as
    :func:`derived_refraction_terms`): a fitted value beyond them is no plate's. A rig without a plate: (0, 0)."""
    m = rig.mirrors
    lo_f, hi_f = PLAUSIBLE_PLATE["thickness_factor"]
    n_lo, n_hi = PLAUSIBLE_PLATE["refractive_index"]
    spread = math.radians(PLAUSIBLE_PLATE["angle_deg"])
    theta = (math.pi / 2 - m.angle_rad) + np.linspace(-spread, spread, 13)[:, None, None]
    n = np.linspace(n_lo, n_hi, 13)[None, :, None]
    d = m.plate_thickness_mm * np.array([lo_f, hi_f])[None, None, :]
    ls = plate_shift_derivative_mm(theta, 1.0, n) * d
    ms = plate_shift_mm(theta, 1.0, n) * d
    return (float(ls.min()), float(ls.max())), (float(ms.min()), float(ms.max()))


#: mm: the least widening of the plausible range a rig file's terms may take (a rig without a plate: 0 +- this).
FILE_MARGIN_MM = 0.5


def file_refraction_terms(rig: Rig) -> tuple[tuple[float, float], tuple[float, float]]:
    """The (low, high) of l and of m, mm, a rig file may hold: :func:`plausible_refraction_terms` widened each
    side by its own width (at least :data:`FILE_MARGIN_MM`). ``fit-refraction`` refuses a fit beyond it, and
    the rig's bounds (psvs.optics.bounds) refuse a file beyond it: one rule for the terms written and read."""
    out = []
    for lo, hi in plausible_refraction_terms(rig):
        pad = max(hi - lo, FILE_MARGIN_MM)
        out.append((lo - pad, hi + pad))
    return out[0], out[1]


def refraction_terms(rig: Rig) -> tuple[float, float]:
    """The rig's (l, m), mm: ``refraction_l_mm`` / ``refraction_m_mm`` when set, else derived."""
    l_der, m_der = derived_refraction_terms(rig)
    m = rig.mirrors
    return (m.refraction_l_mm if m.refraction_l_mm is not None else l_der,
            m.refraction_m_mm if m.refraction_m_mm is not None else m_der)
