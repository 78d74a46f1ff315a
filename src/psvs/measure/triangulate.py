"""Triangulation of matched left/right pixels into frame C: the paper's models and the exact one.

Models
------
``paper``       eqs. (12)-(14): ideal parallel cameras, the plate ignored (biased by ~1 % in depth for a
                3 mm plate: the plate widens the effective baseline by m).
``refraction``  eqs. (15)-(17) with the rig's l, m (derived from d, n, omega_1, or set in the rig file,
                e.g. from :func:`fit_refraction_terms`).
``exact``       both pixels traced through the exact optics (Snell at both plate faces), the two rays
                intersected (midpoint of their closest approach).

Every model answers only what the rig can see. A row is NaN and invalid when a pixel lies off the sensor
(u outside -0.5..W-0.5 or v outside -0.5..H-0.5: no pixel of the camera saw it), when the disparity is
not positive or the rays diverge (they meet behind the rig, if at all), or when the point they give is not
*in front of the rig*: beyond the mirror box, Z greater than the far reach of its mirrors
(:func:`psvs.optics.mirrors.front_z_mm`: the far mirrors' corners, or M3/M4's anchors for unbounded
mirrors). A point behind the camera or inside the box cannot be seen through the mirrors, so a pair of
pixels that triangulates there was mismatched (left and right swapped, a wrong twin), and no number is
given for it.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from psvs._validate import check_points, check_same_length
from psvs.measure.equations import x_eq13, y_eq14, z_eq12, z_eq15
from psvs.measure.refraction_fit import fit_refraction_terms as fit_refraction_terms  # the fit of l, m: its home
from psvs.optics.mirrors import front_z_mm
from psvs.optics.plate import refraction_terms
from psvs.optics.project import in_image, project_points
from psvs.optics.rectify import needs_rectification
from psvs.optics.rig import Rig
from psvs.optics.trace import ideal_sensor_from_pixels, trace_pixels

MODELS = ("paper", "refraction", "exact")


class Triangulation(NamedTuple):
    """points_mm : (N, 3) frame C, mm, NaN rows where invalid. valid : (N,) bool."""

    points_mm: np.ndarray
    valid: np.ndarray


def default_model(rig: Rig) -> str:
    """The triangulation model used when none is asked for: the refraction-corrected closed forms
    (eq. 15) on the paper's geometry, the exact model on a build (misaligned mirrors or a distorting lens:
    the closed forms assume the ideal geometry)."""
    return "exact" if needs_rectification(rig) else "refraction"


def triangulate(left_px, right_px, rig: Rig, model: str = "refraction") -> Triangulation:
    """Triangulate matched pixels of the complex image into frame C.

    Parameters
    ----------
    left_px, right_px : array_like, shape (N, 2)
        Matched (u, v) in the left and right views, px.
    rig : Rig
    model : {'paper', 'refraction', 'exact'}
        See the module docstring.

    Returns
    -------
    Triangulation
        ``points_mm`` (N, 3) mm and ``valid`` (N,). Rows with x_l <= x_r, NaN input, a pixel off the
        sensor, parallel or diverging rays, a point not in front of the rig (Z <= the mirrors' far reach,
        see the module docstring) or (exact) vignetted rays are NaN and invalid.

    Examples
    --------
    >>> from psvs import default_rig
    >>> rig = default_rig().replace(plate_thickness_mm=0.0)
    >>> res = triangulate([[369.5, 239.5]], [[269.5, 239.5]], rig, model="paper")   # 1 mm disparity
    >>> res.points_mm.round(6), res.valid
    (array([[   0.,    0., 1080.]]), array([ True]))
    """
    left = check_points(left_px, "left_px", 2)
    right = check_points(right_px, "right_px", 2)
    check_same_length(left, right, "left_px", "right_px")
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}; got {model!r}")
    if model == "exact":
        res = _triangulate_exact(left, right, rig)
    else:
        res = _triangulate_closed_form(left, right, rig, model)
    return _seen_by_the_rig(res, left, right, rig)


def _seen_by_the_rig(res: Triangulation, left: np.ndarray, right: np.ndarray, rig: Rig) -> Triangulation:
    """``res`` with the rows no scene point can give made NaN and invalid: a pixel off the sensor, or the
    point not beyond the mirror box (Z <= :func:`psvs.optics.mirrors.front_z_mm`)."""
    pts, valid = res.points_mm, res.valid
    with np.errstate(invalid="ignore"):
        valid = valid & in_image(left, rig) & in_image(right, rig) & (pts[:, 2] > front_z_mm(rig))
    if not valid.all():
        pts[~valid] = np.nan
    return Triangulation(pts, valid)


def _triangulate_closed_form(left: np.ndarray, right: np.ndarray, rig: Rig, model: str) -> Triangulation:
    """Eqs. (12)-(14) (``paper``) or (15)-(17) (``refraction``) on matched pixels (N, 2) px."""
    cam, m = rig.camera, rig.mirrors
    f, b, zv = cam.focal_length_mm, m.baseline_mm, rig.virtual_z_mm
    if cam.distorted:
        xl = ideal_sensor_from_pixels(left, cam)[:, 0]
        xr, yr = ideal_sensor_from_pixels(right, cam).T
    else:  # the fast path: eqs. (12)-(17) on raw columns
        (cx, cy), (px, py) = cam.principal_point_px, cam.pixel_pitch_mm
        xl = (left[:, 0] - cx) * px
        xr = (right[:, 0] - cx) * px
        yr = (right[:, 1] - cy) * py
    if model == "paper":
        z = z_eq12(xl, xr, f, b, zv)
    else:
        l_mm, m_mm = refraction_terms(rig)
        z = z_eq15(xl, xr, f, b, l_mm, m_mm, zv)
    valid = np.isfinite(z + yr + left[:, 1])
    pts = np.stack([x_eq13(xr, z, f, b, zv), y_eq14(yr, z, f, b, zv), z]).T  # (N, 3) view of a (3, N) block
    if not valid.all():
        pts[~valid] = np.nan
    return Triangulation(pts, valid)


def twin_rows(left_px, right_px, rig: Rig, model: str = "exact"):
    """Row v (px) in the right view where each matched pair's point really appears, and a validity mask.

    The M1 plate shifts the left view's rows slightly (up to ~0.5 px, with position and depth), so a
    point seen on row v_l lies on row v_l + dv in the right view: triangulate, project into the right view.
    Returns (v_right (N,), valid (N,)).
    """
    pts = triangulate(left_px, right_px, rig, model=model).points_mm
    uv, ok = project_points(pts, rig, "right")
    ok &= np.isfinite(uv[:, 1])
    return uv[:, 1], ok


#: px: how far a twin may lie off the other pixel's epipolar curve (the two exact rays' closest approach,
#: seen at the point's depth) and still be its twin: sub-pixel matches reach 0.1-0.3 px, edge pairs 1 px, a
#: calibrated rig's twins stand 0.05 px off their curves; a pair 2 px off sees two different points.
EPIPOLAR_TOL_PX = 2.0


def epipolar_gap_px(left_px, right_px, rig: Rig) -> np.ndarray:
    """How far each matched pair (N, 2) px stands off being twins, (N,) px: the closest approach of the two
    pixels' exact rays (mm), seen from the camera at the point's depth (mm -> px through f / (Z - z_v) and
    the pixel pitch). NaN where a ray is vignetted or the rays do not meet in front of the camera."""
    left = check_points(left_px, "left_px", 2)
    right = check_points(right_px, "right_px", 2)
    res, gap = _closest_approach(left, right, rig)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = res.points_mm[:, 2] - rig.virtual_z_mm
        px = gap * rig.camera.focal_length_mm / z / min(rig.camera.pixel_pitch_mm)
    return np.where(res.valid & (z > 0), px, np.nan)


def _triangulate_exact(left: np.ndarray, right: np.ndarray, rig: Rig) -> Triangulation:
    return _closest_approach(left, right, rig)[0]


def _closest_approach(left: np.ndarray, right: np.ndarray, rig: Rig) -> tuple[Triangulation, np.ndarray]:
    """Both pixels' exact rays: the midpoint of their closest approach (invalid where a ray is vignetted or
    they meet behind either origin) and the length of that approach (N,) mm."""
    rl = trace_pixels(left, rig, "left")
    rr = trace_pixels(right, rig, "right")
    w0 = rl.origins_mm - rr.origins_mm
    b = np.einsum("ij,ij->i", rl.dirs, rr.dirs)
    d = np.einsum("ij,ij->i", rl.dirs, w0)
    e = np.einsum("ij,ij->i", rr.dirs, w0)
    denom = 1.0 - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (b * e - d) / denom      # along the left ray
        t = (e - b * d) / denom      # along the right ray
    on_left = rl.origins_mm + s[:, None] * rl.dirs
    on_right = rr.origins_mm + t[:, None] * rr.dirs
    pts = 0.5 * (on_left + on_right)
    gap = np.linalg.norm(on_left - on_right, axis=1)
    with np.errstate(invalid="ignore"):
        valid = rl.valid & rr.valid & (denom > 1e-14) & (s > 0) & (t > 0)
    valid &= np.all(np.isfinite(pts), axis=1)
    pts[~valid] = np.nan
    return Triangulation(pts, valid), gap


#: px: the match noise :func:`depth_sigma_mm` assumes unless told (a sub-pixel edge match's; the paper's
#: pixel-level matching is about 0.5 px).
MATCH_SIGMA_PX = 0.1
#: px: the least match noise :func:`depth_sigma_mm` takes: the sharpest sub-pixel edge fits on a camera's pixels
#: reach a few hundredths of a pixel; a noise below this one would call a 0.01 px disparity a point 11 km away,
#: pinned to a millimetre (an adversarial trial's 1e-9 px).
MIN_MATCH_SIGMA_PX = 0.01


def depth_sigma_mm(left_px, right_px, rig: Rig, model: str = "refraction",
                   sigma_px: float = MATCH_SIGMA_PX) -> np.ndarray:
    """How far (mm, shape (N,)) each pair's depth moves when its disparity changes by ``sigma_px`` along the
    row either way (the larger of the two moves, through the same ``model``): the depth's first-order
    uncertainty for a match noise of ``sigma_px``. The right pixel (N, 2) is moved (the left one the other way
    where the moved right pixel would leave what the rig sees: the sensor's edge, a mirror's). inf where the
    smaller disparity cannot be triangulated either way (it does not stand above the noise); a larger
    disparity that cannot (a point near the rig's front) leaves the smaller one's move; NaN where the pair
    itself is invalid. For the paper's parallel cameras it is Z sigma / (d - sigma) of a disparity d (px): it
    passes Z where d <= 2 sigma."""
    if not (np.isfinite(sigma_px) and sigma_px > 0):
        raise ValueError(f"the match noise must be a positive number of px, got {sigma_px!r}")
    if sigma_px < MIN_MATCH_SIGMA_PX:
        raise ValueError(f"the match noise of {sigma_px:g} px is below what any match on a camera's pixels reaches "
                         f"(at least {MIN_MATCH_SIGMA_PX:g} px; a sharp sub-pixel edge match is about 0.05-0.1)")
    left = check_points(left_px, "left_px", 2)
    right = check_points(right_px, "right_px", 2)
    z = triangulate(left, right, rig, model).points_mm[:, 2]
    moves = []
    for step in (sigma_px, -sigma_px):    # the smaller disparity (the right pixel to the right), the larger
        shift = np.array([step, 0.0])
        moved = triangulate(left, right + shift, rig, model)
        other = triangulate(left - shift, right, rig, model)    # the same change of disparity, from the left
        zm = np.where(moved.valid, moved.points_mm[:, 2], np.where(other.valid, other.points_mm[:, 2], np.nan))
        moves.append(np.abs(zm - z))
    far, near = moves
    out = np.where(np.isfinite(far), np.fmax(far, near), np.inf)
    out[~np.isfinite(z)] = np.nan
    return out
