"""Tares: frames of a flat textured surface facing the rig at a known distance along its axis (a wall, a plate
the robot touches), which pin what the twins' rows cannot: depth (``psvs refit --tare``; docs/health.md).

A tare's tiles, triangulated through a trial rig, must lie on a plane through (0, 0, Z): Z its distance from
O, the real camera's optical centre (psvs's depth), its slope free (no wall faces a rig exactly). Each tile's
depth off that plane is a residual in px of disparity (:func:`disparity_per_mm`), the unit its noise comes
in. One tare pins the depth's offset at its distance; the rig's scale (a view turned along its rows against
a longer baseline) it pins only through the small curvature a turned view gives a flat wall: a second tare
at another distance pins it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs.errors import MeasurementError
from psvs.optics.rig import Rig

#: mm, 1 sigma: how well a tare's stated distance from the optical centre O is known, by default (a robot's
#: stated accuracy, as ``psvs handeye`` takes it; a tape from the rig's front knows O's place less well).
TARE_SIGMA_MM = 0.5
#: mm: the least sigma a tare's distance may be stated with: no surface's distance from O is known exactly (a
#: laser tracker's few um, and O's own place on the axis, which a calibration knows to about 0.1 mm).
MIN_TARE_SIGMA_MM = 0.01
#: A tare surface whose points scatter about their best plane by more than this (px of disparity, RMS) and
#: 3 times the tiles' noise is not flat.
TARE_FLAT_PX = 0.5
#: The share of a tare's points that must lie on its plane (the rest: tiles matched wrongly, a bolt, a
#: cable before the wall); fewer, and the surface is not one plane.
TARE_ON_PLANE = 0.8
#: A point lies off a tare's plane when farther from it than this many robust sigmas of them all (and than
#: TARE_FLAT_PX).
OFF_PLANE_SIGMAS = 3.0


#: A depth scale the tares pin to this relative 1 sigma or better is pinned: a 1 % scale (a focus ring turned, a
#: mirror slid in its seat) then stands out at two sigmas.
SCALE_PINNED = 0.005


def tares_scale_sigma(distances_mm, sigma_mm: float) -> float:
    """The relative 1 sigma to which tares at ``distances_mm`` (each known to ``sigma_mm``) pin a depth scale: a
    scale s moves their depths by s (Z - Z_mean), so their readings' slope against Z is s, known to sigma_mm /
    sqrt(sum (Z - Z_mean)^2) (a straight line's slope by least squares); inf for fewer than two distinct
    distances. Two tares at 700 and 720 mm (0.5 mm each): 3.5 %; at 600 and 950 mm: 0.2 %."""
    z = np.asarray(distances_mm, dtype=float)
    spread = float(np.sqrt(np.sum((z - z.mean()) ** 2))) if len(z) else 0.0
    return sigma_mm / spread if spread > 0 else float("inf")


@dataclass(frozen=True)
class Tare:
    """What one tare surface showed: the stated ``distance_mm`` on the axis, the depth there through the old
    calibration (``before_mm``, its best plane) and the refitted (``after_mm``), the plane's slope
    ``slope_deg`` (about Y, about X), its points' ``flat_rms_px`` about it (px of disparity), ``tiles``."""

    distance_mm: float
    before_mm: float
    after_mm: float
    slope_deg: tuple[float, float]
    flat_rms_px: float
    tiles: int


def tare_plane(points_mm: np.ndarray, distance_mm: float | None = None) -> tuple[np.ndarray, float]:
    """The plane Z = c + p X + q Y best through points (n, 3) mm (least squares in Z): ((c, p, q), RMS mm of
    Z about it); with ``distance_mm`` the plane passes through (0, 0, distance_mm) (c fixed, the slope free)."""
    X, Y, Z = np.asarray(points_mm, dtype=float).T
    if distance_mm is None:
        coef = np.linalg.lstsq(np.column_stack([np.ones_like(X), X, Y]), Z, rcond=None)[0]
    else:
        slope = np.linalg.lstsq(np.column_stack([X, Y]), Z - distance_mm, rcond=None)[0]
        coef = np.concatenate([[distance_mm], slope])
    return coef, float(np.sqrt(np.mean(_off_plane_mm(points_mm, coef) ** 2)))


def _off_plane_mm(points_mm: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """Each point's (n, 3) Z minus the plane Z = c + p X + q Y's there, mm (n,)."""
    p = np.asarray(points_mm, dtype=float)
    return p[:, 2] - coef[0] - coef[1] * p[:, 0] - coef[2] * p[:, 1]


def flat_plane(points_mm: np.ndarray, rig: Rig) -> tuple[np.ndarray, float, float, np.ndarray]:
    """(the plane (c, p, q) best through the points (n, 3) on it, their RMS about it in mm and in px of
    disparity, which points (n,) bool lie on it): least squares re-fitted without the points off it
    (:data:`OFF_PLANE_SIGMAS` robust sigmas, MAD-based) until that set settles."""
    points_mm = np.asarray(points_mm, dtype=float)
    per_mm = disparity_per_mm(rig, points_mm[:, 2])
    on = np.ones(len(points_mm), bool)
    for _ in range(10):
        coef, _ = tare_plane(points_mm[on])
        r = _off_plane_mm(points_mm, coef) * per_mm
        sigma = 1.4826 * float(np.median(np.abs(r[on] - np.median(r[on]))))
        now = np.abs(r) <= max(OFF_PLANE_SIGMAS * sigma, TARE_FLAT_PX)
        if now.sum() < 3 or (now == on).all():
            break
        on = now
    coef, rms_mm = tare_plane(points_mm[on])
    return coef, rms_mm, rms_mm * float(np.median(per_mm[on])), on


def disparity_per_mm(rig: Rig, z_mm: np.ndarray) -> np.ndarray:
    """px of disparity per mm of depth at depths ``z_mm`` (any shape): f b / Z^2, f in px (eq. 17's
    derivative; ideal parallel views)."""
    c = rig.camera
    return c.focal_length_mm / min(c.pixel_pitch_mm) * rig.mirrors.baseline_mm / np.asarray(z_mm) ** 2


def depth_residuals_px(points_mm: np.ndarray, distance_mm: float, rig: Rig) -> np.ndarray:
    """Each point's (n, 3) depth off the plane through (0, 0, ``distance_mm``) that fits them best, in px of
    disparity (n,)."""
    coef = tare_plane(points_mm, distance_mm)[0] if len(points_mm) >= 3 else np.array([distance_mm, 0.0, 0.0])
    return _off_plane_mm(points_mm, coef) * disparity_per_mm(rig, points_mm[:, 2])


def check_flat(points_mm: np.ndarray, rig: Rig, noise_px: float, which: str, hint: str = "") -> np.ndarray:
    """Which of the points (n, 3) lie on their best plane (:func:`flat_plane`), (n,) bool; MeasurementError
    when fewer than :data:`TARE_ON_PLANE` of them lie on it or they scatter about it by more than
    :data:`TARE_FLAT_PX` and 3 times the tiles' ``noise_px``: the surface is not flat (each said apart;
    ``hint`` ends the message: what else would explain it)."""
    _, rms_mm, flat_px, on = flat_plane(points_mm, rig)
    limit = max(TARE_FLAT_PX, 3 * noise_px)
    if on.mean() < TARE_ON_PLANE:
        raise MeasurementError(f"{which} is not flat: {100 * on.mean():.0f} % of its points lie on one plane (a tare "
                               f"needs {100 * TARE_ON_PLANE:.0f} %); a tare needs a flat textured surface facing the "
                               f"rig (a wall, a plate){hint}")
    if flat_px > limit:
        raise MeasurementError(f"{which} is not flat: its points scatter {rms_mm:.2f} mm ({flat_px:.2f} px of "
                               f"disparity) about their plane, a flat surface within {limit:.2f} px; a tare needs a "
                               f"flat textured surface facing the rig (a wall, a plate){hint}")
    return on


def tare_record(before_mm: np.ndarray, after_mm: np.ndarray, distance_mm: float, rig: Rig) -> Tare:
    """A :class:`Tare` from the tare's points (n, 3) through the old calibration and the refitted ``rig``."""
    cb = flat_plane(before_mm, rig)[0]
    ca, _, flat_px, _ = flat_plane(after_mm, rig)
    slope = (math.degrees(math.atan(ca[1])), math.degrees(math.atan(ca[2])))
    return Tare(float(distance_mm), float(cb[0]), float(ca[0]), slope, flat_px, len(after_mm))
