"""Fit l and m of eq. (15) to matched pixels of known points, and refuse a fit the points cannot pin.

Eq. (15) is linear in (l, m): z - z_v - b f / D = x_l l / D + f m / D with D = x_l - x_r, so the fit is a
least-squares line through the rows (x_l / D, f / D) -> that depth remainder. A number written into a rig
file is used for every later depth, so the fit answers only when the points support it:

* **Bad input** (``ValueError``): a non-finite value, or a known point not in front of the rig (Z not beyond
  the mirror box, :func:`psvs.optics.mirrors.front_z_mm`: no camera sees it through the mirrors).
* **Repeated rows count once**: a row repeated (the same pixels of the same point) adds no evidence, so
  the rows are made distinct first; the conditioning and its limit are those of the distinct rows, whatever
  the number of copies (:func:`psvs.evidence.distinct_rows`).
* **Too few distinct points** (:class:`~psvs.errors.MeasurementError`): two unknowns need three distinct
  points, two to pin l and m and a third to check them (two are fitted exactly, whatever they are worth).
* **Ill-conditioned** (``MeasurementError``): each point's depth is uncertain by what a sub-pixel
  disparity error does at its depth, dz = (z - z_v)^2 dd / (f b) (eq. 12 differentiated), with
  dd = :data:`DISPARITY_NOISE_PX` px. With the rows weighted by 1/dz and the two columns scaled to unit
  length, the fit's condition number kappa sets the 1-sigma of each term exactly:
  sigma_k = (kappa + 1/kappa) / (2 c_k), c_k the column's length. The limit is the kappa at which that noise
  moves l or m by their own size (the values derived from d, n, omega_1, at least :data:`TERM_FLOOR_MM`):
  kappa_max = g + sqrt(g^2 - 1), g = min_k size_k c_k; beyond it the fit cannot tell the terms from zero.
  A rank-deficient system (every point on one column, say) has kappa ~ 1e16.
* **No plate's terms** (``MeasurementError``): l and m beyond what a plate of the rig's kind gives
  (:func:`psvs.optics.plate.plausible_refraction_terms`: half to twice its thickness, any optical glass,
  omega_1 within 3 deg) by more than 3 of the fit's sigma: the known points' Z measured from another
  origin, in another unit or scale, fit eq. (15) with terms no glass has.
* **Residual above the noise** (``MeasurementError``): the RMS of the fitted depths' residuals is compared
  with the RMS of dz over the points; more than :data:`RESIDUAL_FACTOR` times that means the matches or the
  known points disagree with eq. (15) (a wrong match, a mistyped point, another rig's pixels).
* **One point off** (``MeasurementError``): each point's residual against its own dz; a mistyped point
  among many moves the RMS little, but its own residual stands out beyond what the largest of N noisy
  points reaches (:func:`point_limit`).
* **X, Y off the pixels** (``MeasurementError``): the fit uses depth only, but the rig written is used for
  whole points. Each known point's X, Y is compared with eqs. (16)-(17) at the fitted depth; the RMS of those
  lateral errors may reach :data:`RESIDUAL_FACTOR` times the RMS that the same sub-pixel error explains
  (dd px on the sensor at the point's depth, with the depth's own dz carried through x_r / f), no more: rows
  flipped, columns swapped or X, Y in cm fit l and m exactly and are refused (on the example's six points,
  156 mm and 105 mm RMS against 0.51 mm).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from psvs._validate import check_points, check_same_length
from psvs.errors import MeasurementError
from psvs.evidence import distinct_rows
from psvs.measure.equations import x_eq13, y_eq14
from psvs.optics.mirrors import front_z_mm
from psvs.optics.plate import (
    PLAUSIBLE_PLATE,
    derived_refraction_terms,
    file_refraction_terms,
    plausible_refraction_terms,
)
from psvs.optics.rectify import needs_rectification
from psvs.optics.rig import Rig
from psvs.optics.trace import ideal_sensor_from_pixels

#: px: the disparity error of a sub-pixel match, the upper end of the 0.1-0.3 px that refined matches reach
#: (docs/matching.md): the noise the checks allow for.
DISPARITY_NOISE_PX = 0.3
#: How many times the noise's RMS depth error the fit's RMS residual may reach.
RESIDUAL_FACTOR = 3.0
#: Why eq. (15) fits no build (trial 49: its refusal blamed the user's pairs, made exactly through the build).
BUILD_WORDS = ("this rig file is a build (its mirrors' errors, the box's turn, the lens's distortion), which no l, m "
               "describe: its exact model (the default on a build) traces all of it and needs no refraction terms")
#: The chance that the largest of the points' residuals passes :func:`point_limit` by noise alone.
POINT_FALSE_ALARM = 0.01
#: mm: the smallest term size the conditioning check asks the fit to resolve (a rig without a plate has
#: derived l = m = 0).
TERM_FLOOR_MM = 0.1


class RefractionFit(NamedTuple):
    """l_mm, m_mm of eq. (15); the rows used; the RMS depth residual and the RMS depth noise (mm) that
    :data:`DISPARITY_NOISE_PX` explains at the points' depths; the fit's condition number and its limit."""

    l_mm: float
    m_mm: float
    n_rows: int
    rms_residual_mm: float
    noise_rms_mm: float
    condition: float
    condition_limit: float


def fit_refraction(left_px, right_px, points_mm, rig: Rig) -> RefractionFit:
    """Fit l and m of eq. (15) (least squares in depth) after the checks of the module docstring.

    Parameters
    ----------
    left_px, right_px : array_like, shape (N, 2)
        Matched pixels, px. Rows with x_l <= x_r are left out.
    points_mm : array_like, shape (N, 3)
        The points they see, frame C, mm (only Z enters eq. 15).
    rig : Rig

    Raises
    ------
    ValueError
        Bad input: shapes, a non-finite value, a point not in front of the rig, fewer than 2 rows with x_l > x_r.
    MeasurementError
        The points cannot pin l and m, or they disagree with eq. (15) beyond the noise.
    """
    left = check_points(left_px, "left_px", 2)
    right = check_points(right_px, "right_px", 2)
    pts = check_points(points_mm, "points_mm", 3)
    check_same_length(left, right, "left_px", "right_px")
    check_same_length(left, pts, "left_px", "points_mm")
    _check_input(left, right, pts, rig)
    cam = rig.camera
    f, b = cam.focal_length_mm, rig.mirrors.baseline_mm
    xl = ideal_sensor_from_pixels(left, cam)[:, 0]
    sensor_r = ideal_sensor_from_pixels(right, cam)
    disp = xl - sensor_r[:, 0]
    ok = disp > 0
    if ok.sum() < 2:
        raise ValueError(f"the refraction fit needs at least 2 pairs with a positive disparity (u_l right of u_r), "
                         f"got {int(ok.sum())} of {len(ok)}: are the u_l and u_r columns swapped?")
    distinct = len(np.unique(pts[ok], axis=0))
    if distinct < 3:
        raise MeasurementError(f"{int(ok.sum())} rows hold {distinct} distinct point(s): l and m of eq. (15) need 3 "
                               "distinct points (two pin them, the third checks them)")
    xl, disp, sensor_r, pts = distinct_rows(xl[ok], disp[ok], sensor_r[ok], pts[ok])  # a repeat adds nothing
    ok = np.ones(len(xl), dtype=bool)
    A = np.stack([xl[ok] / disp[ok], f / disp[ok]], axis=1)
    rhs = pts[ok, 2] - rig.virtual_z_mm - b * f / disp[ok]
    dz = (pts[ok, 2] - rig.virtual_z_mm) ** 2 * (DISPARITY_NOISE_PX * cam.pixel_pitch_mm[0]) / (f * b)
    kappa, limit = _conditioning(A, dz, rig)
    (l_mm, m_mm), *_ = np.linalg.lstsq(A, rhs, rcond=None)
    rms = float(np.sqrt(np.mean((rhs - A @ np.array([l_mm, m_mm])) ** 2)))
    noise = float(np.sqrt(np.mean(dz ** 2)))
    if rms > RESIDUAL_FACTOR * noise:
        raise MeasurementError(
            f"the fit's RMS depth residual {rms:.3g} mm is {rms / noise:.1f} times the {noise:.3g} mm RMS that a "
            f"{DISPARITY_NOISE_PX} px disparity error explains at these depths (limit {RESIDUAL_FACTOR:g} times): "
            + (f"eq. (15) is the paper's ideal geometry, and {BUILD_WORDS}" if needs_rectification(rig) else
               "the matches or the known points disagree with eq. (15) (a wrong match, a mistyped point, another rig)"))
    _check_plausible((float(l_mm), float(m_mm)), A / dz[:, None], rig)   # (a systematic error says so first)
    _check_points_alone(rhs - A @ np.array([l_mm, m_mm]), dz, pts)
    _check_lateral(sensor_r, pts[:, 2] - (rhs - A @ np.array([l_mm, m_mm])), pts, dz, rig)   # at eq. (15)'s z
    return RefractionFit(float(l_mm), float(m_mm), int(ok.sum()), rms, noise, kappa, limit)


def point_limit(n: int) -> float:
    """How many times its own depth noise dz one point's residual may reach among ``n`` points: the larger of
    :data:`RESIDUAL_FACTOR` and the level that any of n normal deviates passes with probability at most
    :data:`POINT_FALSE_ALARM` (Bonferroni over both tails: the normal's upper alpha / (2 n) quantile; 3.7 for
    40 points).

    >>> round(point_limit(6), 2), round(point_limit(40), 2)
    (3.14, 3.66)
    """
    from scipy.special import ndtri
    return max(RESIDUAL_FACTOR, float(-ndtri(POINT_FALSE_ALARM / (2.0 * n))))


def _check_points_alone(residual: np.ndarray, dz: np.ndarray, pts: np.ndarray) -> None:
    """Each point's depth residual (mm, (N,)) against its own noise ``dz`` (mm, (N,)): one mistyped point
    among many moves the RMS little (one Z 80 mm off among 40 points passed the RMS test at 2.5 times the
    noise, and the rig written then triangulated 4-5 of its sigmas off), but its own residual stands out."""
    ratio = np.abs(residual) / dz
    k = int(np.argmax(ratio))
    limit = point_limit(len(ratio))
    if ratio[k] > limit:
        x, y, z = pts[k]
        raise MeasurementError(
            f"the known point ({x:.6g}, {y:.6g}, {z:.6g}) mm is {residual[k]:+.3g} mm off eq. (15)'s fit, "
            f"{ratio[k]:.1f} times the {dz[k]:.3g} mm that a {DISPARITY_NOISE_PX} px disparity error gives at its "
            f"depth (limit {limit:.1f} for {len(ratio)} points): a mistyped point or a wrong match; correct or "
            "remove it")


def _check_plausible(terms: tuple[float, float], weighted: np.ndarray, rig: Rig) -> None:
    """MeasurementError when a fitted term lies more than 3 sigma (the fit's, rows ``weighted`` by 1/dz)
    beyond what a plate of the rig's kind can give (:func:`~psvs.optics.plate.plausible_refraction_terms`), or
    beyond what a rig file may hold (:func:`~psvs.optics.plate.file_refraction_terms`: a fit loose enough to
    pass the first would otherwise be written into a file that no command reads back)."""
    sigma = np.sqrt(np.diag(np.linalg.pinv(weighted.T @ weighted)))
    for name, value, (lo, hi), sd in zip("lm", terms, plausible_refraction_terms(rig), sigma, strict=True):
        if not lo - 3 * sd <= value <= hi + 3 * sd:
            f_lo, f_hi = PLAUSIBLE_PLATE["thickness_factor"]
            n_lo, n_hi = PLAUSIBLE_PLATE["refractive_index"]
            raise MeasurementError(
                f"the fitted {name} = {value:.3g} +- {sd:.2g} mm of eq. (15) is no plate's: a plate of "
                f"{f_lo * rig.mirrors.plate_thickness_mm:g}-{f_hi * rig.mirrors.plate_thickness_mm:g} mm, n "
                f"{n_lo:g}-{n_hi:g}, omega_1 within {PLAUSIBLE_PLATE['angle_deg']:g} deg of the rig's gives "
                f"{name} {lo:.3g}-{hi:.3g} mm: the known points disagree with the matches (Z from another origin, "
                "another unit or scale?)")
    for name, value, (f_lo, f_hi) in zip("lm", terms, file_refraction_terms(rig), strict=True):
        if not f_lo <= value <= f_hi:      # within 3 sigma of a plate's, yet no rig file may hold it
            raise MeasurementError(
                f"the fitted {name} = {value:.3g} mm of eq. (15) lies beyond what a plate of the rig's kind gives, "
                f"widened by that range's width ({f_lo:.3g}-{f_hi:.3g} mm): too few or too noisy known points to "
                "pin it, or points from another origin, unit or scale")


def fit_refraction_terms(left_px, right_px, points_mm, rig: Rig) -> tuple[float, float]:
    """(l_mm, m_mm) of eq. (15) fitted to matched pixels of known points: :func:`fit_refraction`'s terms
    (same checks, same errors)."""
    fit = fit_refraction(left_px, right_px, points_mm, rig)
    return fit.l_mm, fit.m_mm


def _check_lateral(sensor_r: np.ndarray, z: np.ndarray, pts: np.ndarray, dz: np.ndarray, rig: Rig) -> None:
    """MeasurementError when the known points' X, Y (``pts`` (N, 3) mm) disagree with eqs. (16)-(17) from the
    right views' sensor points ``sensor_r`` (N, 2) mm at the fitted depths ``z`` (N,) mm beyond
    :data:`RESIDUAL_FACTOR` times what the noise explains (module docstring); ``dz`` (N,) mm is each depth's
    own noise."""
    cam = rig.camera
    f, b = cam.focal_length_mm, rig.mirrors.baseline_mm
    x, y = x_eq13(sensor_r[:, 0], z, f, b, rig.virtual_z_mm), y_eq14(sensor_r[:, 1], z, f, b, rig.virtual_z_mm)
    off = np.hypot(x - pts[:, 0], y - pts[:, 1])
    on_sensor = (z - rig.virtual_z_mm)[:, None] * DISPARITY_NOISE_PX * np.asarray(cam.pixel_pitch_mm) / f  # (N, 2)
    noise = np.hypot(on_sensor, np.abs(sensor_r) / f * dz[:, None])
    rms, allowed = float(np.sqrt(np.mean(off ** 2))), float(np.sqrt(np.mean(np.sum(noise ** 2, axis=1))))
    if rms > RESIDUAL_FACTOR * allowed:
        k = int(np.argmax(off))
        raise MeasurementError(
            f"the known points' X, Y are {rms:.3g} mm RMS off where their pixels put them (eqs. 16-17 at the "
            f"fitted depths), {rms / allowed:.0f} times the {allowed:.3g} mm a {DISPARITY_NOISE_PX} px error "
            f"explains (limit {RESIDUAL_FACTOR:g} times; the worst, row {k + 1}: {off[k]:.3g} mm): X or Y "
            "flipped, swapped, in another unit, or from another origin than the camera's")


def _check_input(left: np.ndarray, right: np.ndarray, pts: np.ndarray, rig: Rig) -> None:
    """ValueError naming the first row with a non-finite value or a point not in front of the rig."""
    for name, arr in (("left_px", left), ("right_px", right), ("points_mm", pts)):
        bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
        if len(bad):
            raise ValueError(f"{name} row {bad[0] + 1} is not finite ({', '.join(f'{v:g}' for v in arr[bad[0]])}): "
                             "every known point needs both pixels and X, Y, Z")
    front = front_z_mm(rig)
    behind = np.flatnonzero(pts[:, 2] <= front)
    if len(behind):
        k = behind[0]
        raise ValueError(f"points_mm row {k + 1}: Z = {pts[k, 2]:g} mm is not in front of the rig (beyond its "
                         f"mirrors, Z > {front:.1f} mm): no camera sees it through the mirrors")


def _conditioning(A: np.ndarray, dz: np.ndarray, rig: Rig) -> tuple[float, float]:
    """The condition number of the fit (rows weighted by 1/dz, columns scaled to unit length) and its limit
    (module docstring); MeasurementError when it is above the limit."""
    W = A / dz[:, None]
    c = np.linalg.norm(W, axis=0)
    size = np.maximum(np.abs(derived_refraction_terms(rig)), TERM_FLOOR_MM)
    s = np.linalg.svd(W / np.where(c > 0, c, 1.0), compute_uv=False)
    kappa = float(s[0] / s[1]) if s[1] > 0 else math.inf
    g = float(np.min(size * c))
    limit = g + math.sqrt(g * g - 1.0) if g >= 1.0 else 1.0
    if kappa > limit or g < 1.0:
        with np.errstate(divide="ignore"):
            sigma = (kappa + 1.0 / kappa) / (2.0 * c) if math.isfinite(kappa) else np.full(2, math.inf)
        raise MeasurementError(
            f"the points do not pin l and m of eq. (15): the fit's condition number is {kappa:.3g} (rows weighted "
            f"by a {DISPARITY_NOISE_PX} px disparity error at their depths, columns scaled), limit {limit:.3g}, "
            f"where that error moves l or m by their own size ({size[0]:.2f}, {size[1]:.2f} mm): l +- "
            f"{sigma[0]:.3g} mm, m +- {sigma[1]:.3g} mm; spread the points over more columns and depths")
    return kappa, limit
