"""Detect the paper's accuracy pattern (Fig. 9: a row of dark circles on a sheet) in a complex image.

Each circle appears twice, once per view. Dark blobs are found by the one blob finder
(:mod:`psvs.targets.discs`: black-hat, Otsu), so they stand out on any local background, including where
one view's circle lies on the other view's sheet, and each is refined to sub-pixel on the grey image
(:func:`psvs.targets.rim.refine_circle`: per-ray half levels, an ellipse fit, blur corrected). The two
views' copies are paired by the rig's geometry (below); without a rig, sorted by u, the first ``count``
belong to the right view only while the copies sit apart (:func:`detect_pattern`).

**Pairing** (:func:`pair_with_start`, and :func:`psvs.accuracy.pattern_measure.measure_pattern` through a
calibrated rig). Which circle of a complex image is whose twin: the two views' copies of a row of circles
paired by the rig's geometry, every consistent way enumerated, and an answer only when exactly one is.

Each circle of the pattern appears once per view. Which detected circle is a left-view image and which
right-view image it pairs with is a combinatorial choice: where the two copies sit side by side, sorting by
u splits them; where they come close or interleave (a pattern nearly as wide as the baseline, a tilted or
off-centre one, a near pattern on a short lens) it does not. So every assignment is tried:

1. **Twins on their epipolar curves, inside the working range.** Circle b can be the right-view twin of
   circle a only when b lies within ``epipolar_px`` of a's epipolar curve *between the working range's
   near and far depths*: a's ray (the rig's exact optics, :func:`psvs.optics.trace.trace_pixels`) sampled
   from ``near_mm`` to ``far_mm`` and projected into the right view (the one twin test of psvs's targets,
   :func:`psvs.targets.twins.twin_distances_px`, which the cards' pairing uses too). That is the rig's
   disparity range for near..far (:func:`psvs.optics.search_range.disparity_range`) traced exactly, lens
   and mirror errors included, so a distorting lens's field edge gets its own disparities.
2. **Every circle used once.** The candidate twins form a directed graph; each perfect matching (all 2n
   circles in n pairs, each circle a left view or a right view) is an assignment.
3. **Equal spacing along the pattern.** Each assignment's twins are triangulated (exact optics); the n
   centres, ordered along their row, must lie on a line, consecutive centres the pattern's spacing apart.
4. **Diameters.** The circles of the assignments left must be the pattern's diameter
   (:mod:`psvs.accuracy.pattern_measure`).

Exactly one assignment must remain: none, or more than one, is a :class:`~psvs.errors.MeasurementError`
saying so (with the nearest candidate's failed check when none fits).

The detector's size range comes from the rig and the working range (:func:`disc_size_range_px`): the
pattern's disc, d f / (pitch (Z - z_v)) px at Z, from ``near_mm`` to ``far_mm``, times the lens's local
scale over the field.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from psvs._validate import check_grey
from psvs.errors import MeasurementError
from psvs.optics.rig import Rig
from psvs.optics.trace import distort, undistort
from psvs.targets.discs import MAX_DIAMETER_PX, MIN_AREA_PX, blob_centre, blob_contours, split_two_discs
from psvs.targets.rim import Ellipse, refine_circle
from psvs.targets.twins import twin_distances_px

#: The least span of grey levels (of 255) in which the pattern's circles are told from the background.
MIN_CONTRAST = 20


@dataclass(frozen=True, eq=False)
class PatternDetection:
    """The pattern's circles in each view, ordered by u: left[k] and right[k] are the same circle."""

    left: list[Ellipse]
    right: list[Ellipse]


def detect_circles(grey: np.ndarray, count: int = 5, max_diameter_px: int = MAX_DIAMETER_PX,
                   min_area_px: float = MIN_AREA_PX) -> list[Ellipse]:
    """The pattern's 2 ``count`` circles (both views, unpaired, ordered by u) in a complex image: dark round
    blobs ``min_area_px`` to ``max_diameter_px`` (:func:`dark_blobs`), refined (:func:`refine_circle`). Where
    a circle of one view overlaps one of the other (a build whose views are turned against each other, a
    pattern wider than the baseline), their union is split in two (:func:`split_two_discs`) when the round
    blobs are too few.

    Raises ValueError for a blank image (nothing to measure in it); MeasurementError, naming the problem, for
    one whose grey levels span less than :data:`MIN_CONTRAST` (too dark to tell the pattern), and when
    the image does not show the pattern asked for: fewer than 2 ``count`` - 1 circles (circles missing or the
    pattern out of view), more than 2 ``count`` (another pattern: the count is checked, never chosen from),
    exactly one fewer (one view shows a circle the other does not: the views disagree), circles not on one row.
    """
    if not isinstance(count, int) or isinstance(count, bool) or count < 2:
        raise ValueError(f"count must be an integer >= 2 (circles in the pattern), got {count!r}")
    grey = check_grey(grey)
    lo, hi, _, _ = cv2.minMaxLoc(grey)
    if hi == lo:
        raise ValueError("image is blank (no contrast): no pattern to find")
    if hi - lo < MIN_CONTRAST:      # a dark frame, not a blank one (trial 45: a 16-bit file of 3..63 was "blank")
        raise MeasurementError(f"the image's contrast is too low to find the pattern: grey levels {lo:g}..{hi:g} "
                               f"of 255 (a range of {hi - lo:g}, at least {MIN_CONTRAST} needed): expose longer or "
                               "light the pattern")
    found = blob_contours(grey, max_diameter_px, min_area_px)
    blobs = [(blob_centre(c), float(np.sqrt(a / np.pi))) for c, a, r in found if r >= 0.6]
    if len(blobs) < 2 * count:
        blobs = _split_merged(found, 2 * count) or blobs
    if len(blobs) > 2 * count:     # more circles than the pattern asked for: not that pattern, nothing to pick
        raise MeasurementError(f"found {len(blobs)} circles, expected {2 * count} ({count} per view): the image "
                               f"shows more circles than the pattern's {count}")
    if len(blobs) == 2 * count - 1:
        raise MeasurementError(f"found {len(blobs)} circles, expected {2 * count} ({count} per view): one view "
                               f"shows a circle the other does not (covered, out of its field, or a blot)")
    if len(blobs) < 2 * count:
        raise MeasurementError(f"found {len(blobs)} circle(s), expected {2 * count} ({count} per view): a circle is "
                               f"missing, the pattern is partly out of view, or its circles run into what lies "
                               f"behind them (each must stand out as a closed outline: a busy or striped "
                               f"background beside the sheet)")
    blobs.sort(key=lambda b: b[0][0])
    circles = [refine_circle(grey, c, r) for c, r in blobs]
    rows = np.array([e.centre_px[1] for e in circles])
    mean_axis = np.mean([np.mean(e.axes_px) for e in circles])
    if np.ptp(rows) > 0.5 * mean_axis + 0.1 * np.ptp([e.centre_px[0] for e in circles]):
        raise MeasurementError("the circles do not lie along one row: not the accuracy pattern")
    return circles


def _split_merged(found, want: int) -> list | None:
    """Blobs with ``want`` discs when some of ``found`` (:func:`blob_contours`) are two discs of the two
    views overlapping: blobs of 1.15-2.2 times the round blobs' median area, the not-round ones first
    (two discs just touching), then the largest, split in two (:func:`split_two_discs`) until there are
    ``want``; None when that does not give exactly ``want``."""
    singles = [a for _, a, r in found if r >= 0.6]
    if not singles:
        return None
    med = float(np.median(singles))
    merged = sorted((i for i, (_, a, _) in enumerate(found) if 1.15 * med <= a <= 2.2 * med),
                    key=lambda i: (found[i][2] >= 0.6, -found[i][1]))
    count, chosen = len(singles), []
    for i in merged:
        if count >= want:
            break
        chosen.append(i)
        count += 1 if found[i][2] >= 0.6 else 2
    if count != want:
        return None
    out = [(blob_centre(c), float(np.sqrt(a / np.pi))) for i, (c, a, r) in enumerate(found)
           if r >= 0.6 and i not in chosen]
    for i in chosen:
        two = split_two_discs(found[i][0])
        if two is None:
            return None
        out += list(two)
    return out


def detect_pattern(grey: np.ndarray, count: int = 5, max_diameter_px: int = MAX_DIAMETER_PX,
                   min_area_px: float = MIN_AREA_PX) -> PatternDetection:
    """Find the pattern's ``count`` circles in both views of a complex image (:func:`detect_circles`) and
    split them by u, the first ``count`` the right view: right only where the two copies sit apart, not
    interleaved. A rig pairs them by its geometry instead (:func:`psvs.targets.pattern.pair_with_start`,
    :func:`psvs.accuracy.pattern_measure.measure_pattern`)."""
    circles = detect_circles(grey, count, max_diameter_px, min_area_px)
    return PatternDetection(circles[count:], circles[:count])


#: At most this many assignments are enumerated: more means the rig's geometry cannot tell the views apart.
MAX_ASSIGNMENTS = 20000
#: A tilted disc, perspective and blur make an image of the disc up to this much wider than d f / (pitch Z).
WIDEN = 1.25
#: A disc's image may be foreshortened to this fraction of its width (a tilt of 75 deg) and still be found.
NARROWEST = 0.25


def lens_scale_range(rig: Rig, samples: int = 15) -> tuple[float, float]:
    """The smallest and largest local scale (ratio of a distorted to an ideal length, any direction) of the
    rig's lens over its sensor: (1, 1) without distortion; a barrel lens shrinks the field's edge."""
    cam = rig.camera
    if not cam.distorted:
        return 1.0, 1.0
    (w, h), (cx, cy), (px, py), f = cam.image_size_px, cam.principal_point_px, cam.pixel_pitch_mm, cam.focal_length_mm
    uu, vv = np.meshgrid(np.linspace(-0.5, w - 0.5, samples), np.linspace(-0.5, h - 0.5, samples))
    xd = np.column_stack([(uu.ravel() - cx) * px / f, (vv.ravel() - cy) * py / f])
    x = undistort(xd, cam.distortion)
    eps = 1e-6
    jx = (distort(x + [eps, 0.0], cam.distortion) - distort(x - [eps, 0.0], cam.distortion)) / (2 * eps)
    jy = (distort(x + [0.0, eps], cam.distortion) - distort(x - [0.0, eps], cam.distortion)) / (2 * eps)
    sv = np.linalg.svd(np.stack([jx, jy], axis=2), compute_uv=False)           # (M, 2) singular values
    return float(sv.min()), float(sv.max())


def disc_size_range_px(rig: Rig, diameter_mm: float, near_mm: float, far_mm: float) -> tuple[float, int]:
    """(min_area_px, max_diameter_px) for :func:`psvs.targets.discs.dark_blobs`: a disc of
    ``diameter_mm`` anywhere in the field at near_mm..far_mm. Its image is d f / (pitch (Z - z_v)) px wide
    at Z, times the lens's local scale (:func:`lens_scale_range`); the widest (at near_mm, the largest
    scale) times :data:`WIDEN` is the black-hat's reach; the smallest area is that of the narrowest (at
    far_mm, the smallest scale) foreshortened to :data:`NARROWEST`, and at least the noise floor
    :data:`~psvs.targets.discs.MIN_AREA_PX`."""
    cam, zv = rig.camera, rig.virtual_z_mm
    f, pitch = cam.focal_length_mm, max(cam.pixel_pitch_mm)
    lo_s, hi_s = lens_scale_range(rig)
    widest = diameter_mm * f / (min(cam.pixel_pitch_mm) * (near_mm - zv)) * hi_s * WIDEN
    narrowest = diameter_mm * f / (pitch * (far_mm - zv)) * lo_s
    area = math.pi / 4 * narrowest * narrowest * NARROWEST
    return max(MIN_AREA_PX, area), int(math.ceil(widest))


def perfect_matchings(edges: np.ndarray, limit: int = MAX_ASSIGNMENTS) -> list[list[tuple[int, int]]]:
    """Every way to split N nodes into pairs (a, b) with ``edges[a, b]`` True (a the left view, b the
    right), each node in exactly one pair; MeasurementError beyond ``limit`` ways."""
    n = len(edges)
    out: list[list[tuple[int, int]]] = []
    used = np.zeros(n, dtype=bool)
    pairs: list[tuple[int, int]] = []

    def walk():
        free = np.flatnonzero(~used)
        if len(free) == 0:
            out.append(sorted(pairs))
            if len(out) > limit:
                raise MeasurementError(f"the circles pair in more than {limit} ways on their epipolar curves "
                                       f"within the working range: the rig's geometry cannot tell the views apart")
            return
        k = free[0]
        used[k] = True
        for other in free[1:]:
            for pair in ((k, other), (other, k)):
                if edges[pair]:
                    used[other] = True
                    pairs.append(pair)
                    walk()
                    pairs.pop()
                    used[other] = False
        used[k] = False

    if n % 2 == 0:
        walk()
    return out


def order_along_row(pairs: np.ndarray, centres_mm: np.ndarray, circles: list[Ellipse]) -> np.ndarray:
    """The permutation that orders pairs along their row of 3-D centres (principal direction), the first the
    one of smallest left-view u."""
    c = centres_mm - centres_mm.mean(axis=0)
    _, _, vt = np.linalg.svd(c)
    t = c @ vt[0]
    order = np.argsort(t)
    u = [circles[pairs[i, 0]].centre_px[0] for i in order]
    return order if u[0] <= u[-1] else order[::-1]


#: A start rig (a design, or a rough guess before calibration) may place twins this far off their epipolar
#: curves: a build's mirrors within a builder's tolerance (tilts of +-0.3 deg, a box turned as much) turn
#: the two views by up to about 2 deg against each other.
START_VIEW_TURN_RAD = math.radians(2.0)
#: ...and misjudge depth (f, b) by up to this factor: the working range is widened by it, and the views'
#: turn moves a twin along its curve as far as across it (a disparity off by the same px). The row's
#: triangulated gaps may then be off the printed spacing by up to this factor either way (a turn of the
#: views changes depth most at the far end: 40 % at 1200 mm on mv1440_misaligned).
START_SCALE = 1.3
START_SPACING_FACTOR = 2.0
#: With a start rig the pattern's row is checked for its shape only: consecutive gaps equal within this
#: fraction of their mean, their mean within START_SPACING_FACTOR of the printed spacing...
START_GAP_TOLERANCE = 0.1
#: ...and every centre within this fraction of a gap of the line through the first and the last (a lens
#: the start rig does not model bows the row: 3.3 mm in 88 at 425 mm, mv1440 seen without its k1 = -0.27).
START_ROW_TOLERANCE = 0.3


def pair_with_start(circles: list[Ellipse], start: Rig, count: int, spacing_mm: float,
                    z_mm: tuple[float, float] = (400.0, 1200.0)):
    """The one assignment of ``circles`` (both views, unpaired) to twins consistent with a *start* rig (not
    yet calibrated: its optics and scale are only roughly right): twins within
    :data:`START_VIEW_TURN_RAD` (as px at the focal length) of their epipolar curves over the working range
    widened by :data:`START_SCALE` (across the curve and along it), and triangulated twins forming a row of
    equal gaps (:data:`START_GAP_TOLERANCE`, :data:`START_ROW_TOLERANCE`) whose mean is the printed spacing
    within a factor :data:`START_SPACING_FACTOR`. Returns the PatternDetection (left[k] twin of right[k],
    along the row); MeasurementError when no assignment, or more than one, is consistent."""
    from psvs.measure.triangulate import triangulate
    cpx = np.array([e.centre_px for e in circles])
    zv = start.virtual_z_mm
    near, far = zv + (z_mm[0] - zv) / START_SCALE, zv + (z_mm[1] - zv) * START_SCALE
    band = start.camera.focal_length_mm / min(start.camera.pixel_pitch_mm) * math.tan(START_VIEW_TURN_RAD)
    across, beyond = twin_distances_px(cpx, start, near, far)
    edges = np.hypot(across, beyond) <= band
    ways = perfect_matchings(edges)
    a, b = np.nonzero(edges)
    found = triangulate(cpx[a], cpx[b], start, model="exact").points_mm
    pts = dict(zip(zip(a.tolist(), b.tolist(), strict=True), found, strict=True))
    fits = []
    for way in ways:
        pairs = np.array(way)
        c = np.array([pts[tuple(p)] for p in way])
        if not np.all(np.isfinite(c)):
            continue
        order = order_along_row(pairs, c, circles)
        c, pairs = c[order], pairs[order]
        gaps = np.linalg.norm(np.diff(c, axis=0), axis=1)
        row = (c[-1] - c[0]) / max(float(np.linalg.norm(c[-1] - c[0])), 1e-12)
        off = np.linalg.norm(np.cross(c - c[0], row), axis=1)
        g = gaps.mean()
        if (np.abs(gaps - g).max() <= START_GAP_TOLERANCE * g and off.max() <= START_ROW_TOLERANCE * g
                and spacing_mm / START_SPACING_FACTOR <= g <= spacing_mm * START_SPACING_FACTOR):
            fits.append(pairs)
    if len(fits) != 1:
        what = "none" if not fits else f"{len(fits)}"
        raise MeasurementError(f"{what} of the {len(ways)} ways to pair the {len(circles)} circles on their "
                               f"epipolar curves through the start rig form a row of {count} circles "
                               f"{spacing_mm:g} mm apart: the image cannot tell which circle is whose twin")
    return PatternDetection([circles[i] for i in fits[0][:, 0]], [circles[i] for i in fits[0][:, 1]])


def detect_with_start(grey: np.ndarray, start: Rig, count: int = 5, spacing_mm: float = 20.0,
                      diameter_mm: float = 10.0, z_mm: tuple[float, float] = (400.0, 1200.0)):
    """The pattern's circles found at the sizes a start rig gives them over the working range (widened by
    :data:`START_SCALE`) and paired by :func:`pair_with_start`: a robot sweep's images before calibration."""
    zv = start.virtual_z_mm
    near, far = zv + (z_mm[0] - zv) / START_SCALE, zv + (z_mm[1] - zv) * START_SCALE
    min_area, max_diameter = disc_size_range_px(start, diameter_mm, near, far)
    circles = detect_circles(grey, count, max_diameter_px=max_diameter, min_area_px=min_area)
    return pair_with_start(circles, start, count, spacing_mm, z_mm)
