"""Measure the paper's accuracy pattern (Table I's columns): depth Z, circle diameters and the distance
between the first and last circle centres, from one complex image.

A measurement is checked against the pattern it claims to be before it is given
(:class:`~psvs.errors.MeasurementError` with the check, the value measured, the value expected and the
tolerance when they disagree). The image must be the rig's sensor size (``ValueError``: a resized or cropped
image changes every pixel's ray). Then, in this order:

1. **The count.** Exactly 2 ``count`` circles (:func:`psvs.targets.pattern.detect_circles`, at the sizes
   the rig gives the pattern over the working range): more is not the pattern asked for, not something to
   choose from; one fewer is a circle one view shows and the other does not.
2. **Pairing** (:mod:`psvs.targets.pattern`, :func:`pair_pattern`). Every assignment of the circles to
   twins is enumerated: a circle's right-view twin lies on its epipolar curve between the working range's
   near and far depths (the rig's exact optics: mirror errors, lens; disparity x_l - x_r > 0 inside the
   rig's range), every circle used once. Another build's image, or the wrong rig, puts twins pixels off
   their curves: no assignment.
3. **Spacings.** An assignment's triangulated centres, along their row: consecutive ones the pattern's
   spacing apart and the first and last (n - 1) spacings (3-D distances).
4. **Diameters.** Each circle's diameter matches the pattern's, and the circles are round: on average over
   the pattern, their 3-D rims (in their plane) are no wider than tall, and no taller than wide
   (:func:`roundness_problem`). A pixel pitch or an image stretched along the rows makes every circle an
   ellipse whose mean diameter can still pass: a 10 % stretch read Z 10 % short, every other check passing.
   Over the Table I distances (440-1123 mm), flat and tilted up to 25 deg, through the ideal rig, the
   misaligned build and both 1440 x 1080 rigs, the mean stretch is at most 0.71 of its tolerance; a 3 %
   stretch at 640 mm is 1.2 times it, 5 % at 1000 mm 1.1 times (a stretch along the columns leaves Z as it is).

Exactly one assignment must pass 3 and 4; none (the nearest one's failed check is named) or more than one
is a MeasurementError.

The tolerances come from how precisely the detector locates an edge, :data:`EDGE_PX` px in one view
(a rim point or an ellipse centre), converted to mm by the pixel footprint at the pattern's depth,
(Z - z_v) pitch / f, and multiplied by :data:`MARGIN`. A diameter spans two rims and a twin's epipolar
distance two centres: 2 EDGE_PX px. A spacing spans two centres (2 EDGE_PX px across) and, along the
row's slope out of the image plane (sin theta, from the centres), their depths: each depth moves by
(Z - z_v)^2 pitch dd / (f b) for a disparity error dd = 2 EDGE_PX px. On the renders of every Table I
distance (440-1123 mm), flat and on the robot's holder, through the ideal rig and the misaligned build,
the largest errors are 0.55 px (a diameter), 0.2 px (a spacing) and 0.11 px (an epipolar distance),
against tolerances of 1 px and more. The misaligned build's images measured with the ideal rig, and the
ideal rig's with the build's, put every twin 8.6-10.3 px off its curve (and the circles 25-29 mm wide).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs._validate import check_positive
from psvs.errors import MeasurementError
from psvs.measure.triangulate import triangulate
from psvs.optics.mirrors import front_z_mm
from psvs.optics.project import epipolar_curve_px, project_points
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels
from psvs.targets.pattern import (
    PatternDetection,
    detect_circles,
    disc_size_range_px,
    order_along_row,
    perfect_matchings,
)
from psvs.targets.rim import EDGE_PX, Ellipse
from psvs.targets.twins import twin_distances_px

#: The tolerances are this many times the error the edges' bounds add up to.
MARGIN = 2.0
#: ... and the circles' mean stretch's (:func:`roundness_problem`) this many: rendered patterns tilted 15 deg
#: at 1000 mm read up to 0.89 of twice the bound (the rims' noise grows with the tilt), a 3 % stretch 1.5.
ROUND_MARGIN = 2.5


@dataclass(frozen=True, eq=False)
class PatternMeasurement:
    """Z_mm: mean depth of the circle centres; diameters_mm (n,); diameter_mm: their mean;
    first_last_distance_mm: |c_first - c_last|; centres_mm (n, 3), frame C; stretch_mm (n,) how much wider
    than tall each circle's rim is in its plane (None: not measured)."""

    Z_mm: float
    diameters_mm: np.ndarray
    diameter_mm: float
    first_last_distance_mm: float
    centres_mm: np.ndarray
    stretch_mm: np.ndarray | None = None

    def to_dict(self) -> dict:
        """The measurement as JSON-ready values: Z, the mean diameter and the first-last distance (mm), each
        circle's diameter and centre (mm)."""
        return {"Z_mm": self.Z_mm, "diameter_mm": self.diameter_mm,
                "first_last_distance_mm": self.first_last_distance_mm,
                "diameters_mm": self.diameters_mm.tolist(), "centres_mm": self.centres_mm.tolist()}


def _implicit(e: Ellipse, uv: np.ndarray) -> np.ndarray:
    """The ellipse's implicit function at pixels uv (..., 2): < 0 inside, 0 on the rim, > 0 outside."""
    a, b = e.axes_px
    c, s = np.cos(e.angle_rad), np.sin(e.angle_rad)
    x, y = uv[..., 0] - e.centre_px[0], uv[..., 1] - e.centre_px[1]
    return ((x * c + y * s) / a) ** 2 + ((-x * s + y * c) / b) ** 2 - 1.0


def epipolar_twins(left_px: np.ndarray, right: Ellipse, rig: Rig, z_mm: tuple[float, float], first: np.ndarray,
                   samples: int = 161) -> np.ndarray:
    """Where the epipolar curves of left-view rim points cross the right view's ellipse, (N, 2) px (NaN where
    they do not): each left pixel's ray (exact optics, any build) is sampled at depths z_mm[0]..z_mm[1],
    projected into the right view, and the crossing refined on that curve; ``first`` (N,) bool picks the
    crossing of smaller u (the rim's left end), else the larger."""
    n = len(left_px)
    rays = trace_pixels(left_px, rig, "left")
    z = np.linspace(*z_mm, samples)
    t = (z[None, :] - rays.origins_mm[:, 2:3]) / rays.dirs[:, 2:3]
    pts = rays.origins_mm[:, None, :] + t[..., None] * rays.dirs[:, None, :]
    uv, ok = project_points(pts.reshape(-1, 3), rig, "right")
    uv = uv.reshape(n, samples, 2)
    f = np.where(ok.reshape(n, samples), _implicit(right, uv), np.nan)
    out = np.full((n, 2), np.nan)
    for k in range(n):
        if not rays.valid[k]:
            continue
        cross = np.flatnonzero(np.sign(f[k, :-1]) * np.sign(f[k, 1:]) < 0)
        if len(cross) == 0:
            continue
        at = [c + f[k, c] / (f[k, c] - f[k, c + 1]) for c in cross]          # linear in the sample index
        pos = [uv[k, c] + (a - c) * (uv[k, c + 1] - uv[k, c]) for c, a in zip(cross, at, strict=True)]
        out[k] = min(pos, key=lambda q: q[0]) if first[k] else max(pos, key=lambda q: q[0])
    return out


def _rim_points(left: Ellipse, right: Ellipse, rig: Rig, model: str, z_mm: float, rows: int = 15) -> np.ndarray:
    """3-D rim points (M, 3) of one circle: both ends of row chords of the left view's ellipse, each paired
    with the point where its epipolar curve (the exact optics of the rig as built: rows of the two views
    need not agree) crosses the right view's ellipse, near the circle's depth ``z_mm``."""
    b = max(left.axes_px) * 0.85
    ends, first = [], []
    for v in np.linspace(left.centre_px[1] - b, left.centre_px[1] + b, rows):
        cl = left.row_crossings(v)
        if cl is not None:
            ends += [[cl[0], v], [cl[1], v]]
            first += [True, False]
    if not ends:
        return np.zeros((0, 3))
    lp = np.array(ends)
    rp = epipolar_twins(lp, right, rig, (z_mm - 80.0, z_mm + 80.0), np.array(first))
    keep = np.all(np.isfinite(rp), axis=1)
    return triangulate(lp[keep], rp[keep], rig, model=model).points_mm


def _circle_fit(points: np.ndarray) -> tuple[float, float]:
    """(diameter, stretch) mm of 3-D rim points (M, 3) in their PCA plane: the least-squares (Kasa) circle's
    diameter, and how much wider than tall they are (:func:`_stretch`); NaN for fewer than 5 points."""
    p = points[np.all(np.isfinite(points), axis=1)]
    if len(p) < 5:
        return float("nan"), float("nan")
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c)
    xy = (p - c) @ vt[:2].T
    A = np.column_stack([2 * xy, np.ones(len(xy))])
    rhs = (xy ** 2).sum(axis=1)
    (x0, y0, k), *_ = np.linalg.lstsq(A, rhs, rcond=None)
    return float(2 * np.sqrt(k + x0 * x0 + y0 * y0)), _stretch(p - c, vt[2])


def _stretch(p: np.ndarray, normal: np.ndarray) -> float:
    """mm: how much wider than tall rim points (M, 3) about their centre are, in their plane (unit ``normal``):
    the axes of the ellipse fitted with its axes along the camera's X and Y projected into the plane,
    2 (r_x - r_y). A circle gives 0 within its rim points' noise; a pixel pitch or an image stretched along
    the rows makes every circle of the pattern wider alike."""
    ex = np.array([1.0, 0.0, 0.0]) - normal[0] * normal
    ex /= np.linalg.norm(ex)
    ey = np.cross(normal, ex)
    x, y = p @ ex, p @ ey
    (a, b, cx, cy), *_ = np.linalg.lstsq(np.column_stack([x * x, y * y, x, y]), np.ones(len(x)), rcond=None)
    den = 1.0 + cx * cx / (4 * a) + cy * cy / (4 * b)        # (x - x0)^2 a + (y - y0)^2 b = den
    if not (a > 0 and b > 0 and den > 0):
        return float("nan")
    return float(2 * (np.sqrt(den / a) - np.sqrt(den / b)))


def footprint_mm(rig: Rig, z_mm: float) -> float:
    """The width (mm) one pixel covers at depth ``z_mm``: (Z - z_v) pitch / f."""
    cam = rig.camera
    return (z_mm - rig.virtual_z_mm) * cam.pixel_pitch_mm[0] / cam.focal_length_mm


def epipolar_distance_px(left_px, right_px, rig: Rig, samples: int = 1024) -> np.ndarray:
    """Distance (px) of each right-view pixel from the epipolar curve of its left-view twin, (N,): the left
    pixel's ray (exact optics, any build) from the front of the rig (:func:`psvs.optics.mirrors.front_z_mm`)
    to the depth of a 0.5 px disparity, sampled evenly in disparity, projected into the right view. NaN
    where the left ray is vignetted or nothing of it projects."""
    left, right = np.atleast_2d(left_px).astype(float), np.atleast_2d(right_px).astype(float)
    rays = trace_pixels(left, rig, "left")
    cam = rig.camera
    f, b, pitch = cam.focal_length_mm, rig.mirrors.baseline_mm, cam.pixel_pitch_mm[0]
    z = rig.virtual_z_mm + b * f / (np.linspace(cam.image_size_px[0], 0.5, samples) * pitch)
    z = z[z > front_z_mm(rig)]
    out = np.full(len(left), np.nan)
    for k in np.flatnonzero(rays.valid):
        uv = epipolar_curve_px(rays.origins_mm[k], rays.dirs[k], z, rig)
        if len(uv) < 2:
            continue
        a, ab = uv[:-1], np.diff(uv, axis=0)
        s = np.clip(np.einsum("ij,ij->i", right[k] - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0, 1)
        out[k] = float(np.min(np.linalg.norm(a + s[:, None] * ab - right[k], axis=1)))
    return out


def check_twins(det: PatternDetection, rig: Rig) -> None:
    """MeasurementError unless every circle's left centre lies right of its right-view twin (disparity > 0)
    and within MARGIN x 2 EDGE_PX px of the twin's epipolar curve (the module docstring)."""
    lc = np.array([e.centre_px for e in det.left])
    rc = np.array([e.centre_px for e in det.right])
    disp = lc[:, 0] - rc[:, 0]
    if np.any(disp <= 0):
        k = int(np.argmin(disp))
        raise MeasurementError(f"circle {k + 1}'s twins have disparity {disp[k]:.1f} px, expected > 0: they are not "
                               "the left and the right view of one point (not a PSVS image of the pattern)")
    dist = epipolar_distance_px(lc, rc, rig)
    tol = MARGIN * 2 * EDGE_PX
    bad = np.flatnonzero(~(dist <= tol))
    if len(bad):
        k = bad[np.argmax(np.nan_to_num(dist[bad], nan=np.inf))]
        what = "off the rig's field" if np.isnan(dist[k]) else f"{dist[k]:.2f} px"
        raise MeasurementError(f"circle {k + 1}'s right-view centre is {what} from its twin's epipolar curve "
                               f"through this rig, tolerance {tol:g} px (two centres within {EDGE_PX} px, margin "
                               f"{MARGIN:g}): the image was taken through other optics than the rig's")


def diameter_problem(diameters_mm: np.ndarray, z_mm: float, rig: Rig, diameter_mm: float) -> tuple[float, str]:
    """(worst error / tolerance, the reason when it is over 1, else '') of circle diameters (n,) mm against
    ``diameter_mm`` at depth ``z_mm`` (the module docstring); NaN diameters are infinitely wrong."""
    px = footprint_mm(rig, z_mm)
    tol_d = MARGIN * 2 * EDGE_PX * px
    err = np.abs(diameters_mm - diameter_mm)
    k = int(np.argmax(np.nan_to_num(err, nan=np.inf)))
    if np.isnan(err[k]):
        return np.inf, (f"circle {k + 1}'s diameter cannot be measured: too few of its rim points have a twin on "
                        "their epipolar curves through this rig")
    ratio = float(err[k] / tol_d)
    return ratio, ("" if ratio <= 1 else
                   f"circle {k + 1}'s diameter is {diameters_mm[k]:.3f} mm, the pattern's {diameter_mm:g} mm, "
                   f"tolerance {tol_d:.3f} mm at Z = {z_mm:.0f} mm ({MARGIN * 2 * EDGE_PX:g} px of {px:.3f} mm: "
                   f"two rims within {EDGE_PX} px, margin {MARGIN:g})")


def roundness_problem(stretch_mm: np.ndarray | None, z_mm: float, rig: Rig) -> tuple[float, str]:
    """(|mean stretch| / its tolerance, the reason when it is over 1, else '') of circles each wider than tall
    by ``stretch_mm`` (n,) mm in their plane (:func:`_stretch`; None or NaN: not judged), at depth ``z_mm``. A
    stretch along the rows (a pixel pitch or an image wrong along one axis) widens every circle alike; the
    rims' noise does not: the tolerance is a diameter's (:func:`diameter_problem`, with :data:`ROUND_MARGIN`) over
    sqrt(n)."""
    s = np.asarray([] if stretch_mm is None else stretch_mm, float)
    s = s[np.isfinite(s)]
    if len(s) < 2:
        return 0.0, ""
    tol = ROUND_MARGIN * 2 * EDGE_PX * footprint_mm(rig, z_mm) / np.sqrt(len(s))
    ratio = float(abs(s.mean()) / tol)
    return ratio, ("" if ratio <= 1 else
                   f"the circles are not round: {len(s)} of them are {'wider' if s.mean() > 0 else 'taller'} than "
                   f"{'tall' if s.mean() > 0 else 'wide'} by {abs(s.mean()):.3f} mm on average, tolerance {tol:.3f} mm "
                   f"at Z = {z_mm:.0f} mm (the image or the rig's pixel pitch stretched along one axis)")


def rim_problem(m: PatternMeasurement, rig: Rig, diameter_mm: float) -> tuple[float, str]:
    """(ratio, reason) of the circles' rims: their diameters' (:func:`diameter_problem`), or, when those pass,
    their roundness's (:func:`roundness_problem`)."""
    ratio, why = diameter_problem(m.diameters_mm, m.Z_mm, rig, diameter_mm)
    return (ratio, why) if why else max((ratio, why), roundness_problem(m.stretch_mm, m.Z_mm, rig))


def spacing_problem(centres_mm: np.ndarray, rig: Rig, spacing_mm: float) -> tuple[float, str]:
    """(worst error / tolerance, the reason when it is over 1, else '') of centres (n, 3) mm in row order:
    consecutive centres ``spacing_mm`` apart and the first and the last (n - 1) ``spacing_mm`` (a straight
    row), within the tolerance of the module docstring at their mean depth."""
    c = centres_mm
    z = float(c[:, 2].mean())
    px = footprint_mm(rig, z)
    row = c[-1] - c[0]
    length = max(float(np.linalg.norm(row)), 1e-12)
    slope = abs(row[2]) / length                                       # sin of the row's angle out of the image
    cam = rig.camera
    dz = ((z - rig.virtual_z_mm) ** 2 * cam.pixel_pitch_mm[0] * 2 * EDGE_PX
          / (cam.focal_length_mm * rig.mirrors.baseline_mm))      # a centre's depth for a 2 EDGE_PX disparity
    tol_s = MARGIN * (2 * EDGE_PX * px + 2 * dz * slope)
    n = len(c)
    gaps = np.linalg.norm(np.diff(c, axis=0), axis=1)
    err = np.abs(gaps - spacing_mm)
    k = int(np.argmax(err))
    span_err = abs(length - (n - 1) * spacing_mm)                     # a bent row is shorter than straight
    ratio = float(max(err[k], span_err) / tol_s)
    if ratio <= 1:
        return ratio, ""
    i, j, gap, want = (k, k + 1, gaps[k], spacing_mm) if err[k] >= span_err else (0, n - 1, length,
                                                                                     (n - 1) * spacing_mm)
    return ratio, (f"circles {i + 1} and {j + 1} are {gap:.3f} mm apart, the pattern's "
                   f"{'spacing ' if j == i + 1 else ''}{want:g} mm, tolerance {tol_s:.3f} mm at Z = {z:.0f} mm "
                   f"(two centres within {EDGE_PX} px across and in depth, margin {MARGIN:g})")


def check_geometry(m: PatternMeasurement, rig: Rig, spacing_mm: float, diameter_mm: float) -> None:
    """MeasurementError unless every diameter matches ``diameter_mm``, every circle is round and the centres
    lie on a row, each pair of consecutive ones ``spacing_mm`` apart, within the tolerances of the module
    docstring at the pattern's depth."""
    for ratio, why in (rim_problem(m, rig, diameter_mm), spacing_problem(m.centres_mm, rig, spacing_mm)):
        if why:
            raise MeasurementError(why)


def check_pattern_sizes(spacing_mm: float, diameter_mm: float,
                        names: tuple[str, str] = ("spacing_mm", "diameter_mm")) -> tuple[float, float]:
    """(spacing_mm, diameter_mm) if both are finite and > 0 and the circles do not touch, else ValueError
    naming them as ``names`` (e.g. the command's options)."""
    s = check_positive(spacing_mm, names[0], "mm")
    d = check_positive(diameter_mm, names[1], "mm")
    if d >= s:
        raise ValueError(f"{names[1]} ({d:g} mm) must be less than {names[0]} ({s:g} mm): the circles would touch")
    return s, d


#: How a refusal adds that the pattern may stand outside the working range searched (:func:`without_range_hint`).
_OUTSIDE = (", or the pattern stands outside the working range", "; or the pattern lies outside the working range")


def without_range_hint(message: str) -> str:
    """A refusal of :func:`measure_pattern` without its hint that the pattern may stand outside the working
    range (and the options that widen it): for a caller that placed the pattern at a known distance itself
    (Table I's test distances)."""
    for marker in _OUTSIDE:
        message = message.split(marker)[0]
    return message


def measure_pattern(grey: np.ndarray, rig: Rig, model: str = "exact", count: int = 5,
                    detection: PatternDetection | None = None, spacing_mm: float = 20.0,
                    diameter_mm: float = 10.0, z_mm: tuple[float, float] = (400.0, 1200.0)) -> PatternMeasurement:
    """Table I's columns for one complex image of a pattern of ``count`` circles of ``diameter_mm``,
    ``spacing_mm`` apart (the paper's: 5, 10 mm, 20 mm) somewhere in the working range ``z_mm`` = (near,
    far) mm, after the checks of the module docstring.

    The circles are found at the sizes the rig gives them over the working range
    (:func:`psvs.targets.pattern.disc_size_range_px`) and paired by the rig's geometry
    (:func:`pair_pattern`); a given ``detection`` is taken as paired (left[k] twin of right[k]) and only
    checked. Raises ValueError for an image that is not the rig's sensor size (or not the pattern: blank,
    circles missing or not on one row) and MeasurementError when what was found disagrees with the pattern
    or pairs in more than one consistent way."""
    spacing_mm, diameter_mm = check_pattern_sizes(spacing_mm, diameter_mm)
    near_mm, far_mm = (float(z) for z in z_mm)
    if not 0 < near_mm < far_mm:
        raise ValueError(f"working range must satisfy 0 < near < far, got near={near_mm!r}, far={far_mm!r}")
    grey = np.asarray(grey)
    w, h = rig.camera.image_size_px
    if grey.shape[:2] != (h, w):
        raise ValueError(f"image is {grey.shape[1]}x{grey.shape[0]} px but the rig's camera is {w}x{h} px")
    if detection is not None:
        check_twins(detection, rig)
        circles = list(detection.left) + list(detection.right)
        n = len(detection.left)
        return _measure_given(circles, np.column_stack([np.arange(n), n + np.arange(n)]), rig, model,
                              spacing_mm, diameter_mm)
    min_area, max_diameter = disc_size_range_px(rig, diameter_mm, near_mm, far_mm)
    try:
        circles = detect_circles(grey, count, max_diameter_px=max_diameter, min_area_px=min_area)
    except MeasurementError as exc:
        if "circle(s)" not in str(exc):
            raise
        # the sizes looked for come from the working range: a pattern outside it is the same few circles
        raise MeasurementError(f"{exc}{_OUTSIDE[0]} {near_mm:g}-{far_mm:g} mm "
                               f"(its circles looked for {2 * math.sqrt(min_area / math.pi):.0f}-{max_diameter:.0f} "
                               "px across): give --near-mm/--far-mm that hold it") from None
    return pair_pattern(circles, rig, model, (near_mm, far_mm), spacing_mm, diameter_mm)


def _measurement(circles: list[Ellipse], pairs: np.ndarray, centres: np.ndarray, rig: Rig,
                 model: str) -> PatternMeasurement:
    fits = np.array([_circle_fit(_rim_points(circles[a], circles[b], rig, model, float(c[2])))
                     for (a, b), c in zip(pairs, centres, strict=True)]).reshape(-1, 2)
    diam = fits[:, 0]
    return PatternMeasurement(float(centres[:, 2].mean()), diam, float(np.nanmean(diam)) if np.any(np.isfinite(diam))
                              else float("nan"), float(np.linalg.norm(centres[-1] - centres[0])), centres, fits[:, 1])


def _measure_given(circles, pairs, rig, model, spacing_mm, diameter_mm) -> PatternMeasurement:
    lc = np.array([circles[a].centre_px for a, _ in pairs])
    rc = np.array([circles[b].centre_px for _, b in pairs])
    centres = triangulate(lc, rc, rig, model=model).points_mm
    if not np.all(np.isfinite(centres)):
        k = int(np.flatnonzero(~np.all(np.isfinite(centres), axis=1))[0])
        raise MeasurementError(f"circle {k + 1}'s twins do not triangulate to a point in front of the rig "
                               f"(beyond Z = {front_z_mm(rig):.1f} mm) with the {model} model")
    m = _measurement(circles, pairs, centres, rig, model)
    check_geometry(m, rig, spacing_mm, diameter_mm)
    return m


def _no_twins(dist: np.ndarray, tol: float, circles: list[Ellipse], z_mm: tuple[float, float]) -> str:
    """The reason no assignment exists: the circle farthest from any twin (as a left or a right view)."""
    best = np.minimum(dist.min(axis=1), dist.min(axis=0))
    k = int(np.argmax(best))
    u, v = circles[k].centre_px
    near = "no curve" if not np.isfinite(best[k]) else f"{best[k]:.2f} px from the nearest"
    lone = (f"the circle at ({u:.1f}, {v:.1f}) px has no twin: {near}, tolerance {tol:g} px (two centres within "
            f"{EDGE_PX} px, margin {MARGIN:g})" if best[k] > tol else "the candidate twins leave a circle unpaired")
    return (f"no pairing of the {len(circles)} circles puts every twin on its epipolar curve through this rig "
            f"within {z_mm[0]:g}-{z_mm[1]:g} mm: {lone}: the image was taken through other optics than the rig's, "
            f"or the pattern lies outside the working range")


def pair_pattern(circles: list[Ellipse], rig: Rig, model: str, z_mm: tuple[float, float], spacing_mm: float,
                 diameter_mm: float) -> PatternMeasurement:
    """The measurement of the one assignment of ``circles`` (both views, unpaired) to twins that the rig's
    geometry and the pattern allow (:mod:`psvs.targets.pattern`): twins within MARGIN x 2 EDGE_PX px of
    their epipolar curves between z_mm = (near, far), then the row's spacing, then the diameters. None, or
    more than one, is a MeasurementError."""
    cpx = np.array([e.centre_px for e in circles])
    across, beyond = twin_distances_px(cpx, rig, *z_mm)
    dist = np.hypot(across, beyond)
    tol = MARGIN * 2 * EDGE_PX
    ways = perfect_matchings(dist <= tol)
    if not ways:
        raise MeasurementError(_no_twins(dist, tol, circles, z_mm))
    a, b = np.nonzero(dist <= tol)
    found = triangulate(cpx[a], cpx[b], rig, model=model).points_mm
    pts = dict(zip(zip(a.tolist(), b.tolist(), strict=True), found, strict=True))
    tried = []                     # (stage reached, error ratio, reason, pairs, centres)
    for way in ways:
        pairs = np.array(way)
        c = np.array([pts[tuple(p)] for p in way])
        if not np.all(np.isfinite(c)):
            tried.append((0, np.inf, f"a pair of twins does not triangulate in front of the rig with the {model} "
                                     "model", pairs, c))
            continue
        order = order_along_row(pairs, c, circles)
        ratio, why = spacing_problem(c[order], rig, spacing_mm)
        tried.append((1, ratio, why, pairs[order], c[order]))
    fits = []
    for k, (stage, ratio, why, pairs, c) in enumerate(tried):
        if stage == 1 and not why:
            m = _measurement(circles, pairs, c, rig, model)
            ratio, why = rim_problem(m, rig, diameter_mm)
            tried[k] = (2, ratio, why, pairs, c)
            if not why:
                fits.append(m)
    if len(fits) == 1:
        return fits[0]
    if len(fits) > 1:
        zs = ", ".join(f"{m.Z_mm:.1f}" for m in sorted(fits, key=lambda m: m.Z_mm))
        raise MeasurementError(f"the {len(circles)} circles pair consistently with the pattern in {len(fits)} ways "
                               f"(Z = {zs} mm): the image cannot tell which circle is whose twin")
    def nearness(t):     # the furthest check passed; among rows, the gaps nearest the spacing (in spacings)
        stage, ratio, _, _, c = t
        if stage != 1:
            return stage, -ratio
        gaps = np.linalg.norm(np.diff(c, axis=0), axis=1)
        return stage, -float(np.abs(gaps - spacing_mm).max() / spacing_mm)

    stage, ratio, why, _, c = max(tried, key=nearness)
    # twins of a pattern outside the range can stand on other twins' curves: no pairing then fits
    hint = (f"{_OUTSIDE[1]} {z_mm[0]:g}-{z_mm[1]:g} mm: give --near-mm/--far-mm "
            f"that hold it")
    if len(ways) == 1:
        raise MeasurementError(why + hint)
    raise MeasurementError(f"none of the {len(ways)} ways to pair the circles on their epipolar curves fits the "
                           f"pattern; the nearest (Z = {np.nanmean(c[:, 2]):.0f} mm): {why}{hint}")
