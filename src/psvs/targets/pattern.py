"""Detect the paper's accuracy pattern (Fig. 9: a row of dark circles on a sheet) in a complex image.

Each circle appears twice, once per view. Dark blobs are found by the one blob finder
(:mod:`psvs.targets.discs`: black-hat, Otsu), so they stand out on any local background, including where
one view's circle lies on the other view's sheet, and each is refined to sub-pixel on the grey image
(:func:`psvs.targets.rim.refine_circle`: per-ray half levels, an ellipse fit, blur corrected). The two
views' copies are paired by the rig's geometry (:mod:`psvs.targets.pairing`): sorted by u, the first
``count`` belong to the right view only while the copies sit apart (:func:`detect_pattern`).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs._validate import check_grey
from psvs.errors import MeasurementError
from psvs.targets.discs import MAX_DIAMETER_PX, MIN_AREA_PX, blob_centre, blob_contours, split_two_discs
from psvs.targets.rim import Ellipse, refine_circle


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

    Raises ValueError naming the problem: blank image, fewer than 2 ``count`` - 1 circles (circles missing or
    the pattern out of view), circles not on one row; MeasurementError for more circles than 2 ``count``
    (the image shows another pattern than the one asked for: the count is checked, never chosen from) or
    exactly one fewer (one view shows a circle the other does not: the views disagree).
    """
    if not isinstance(count, int) or isinstance(count, bool) or count < 2:
        raise ValueError(f"count must be an integer >= 2 (circles in the pattern), got {count!r}")
    grey = check_grey(grey)
    lo, hi, _, _ = cv2.minMaxLoc(grey)
    if hi - lo < 20:
        raise ValueError("image is blank (no contrast): no pattern to find")
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
        raise ValueError(f"found {len(blobs)} circle(s), expected {2 * count} ({count} per view): a circle is "
                         f"missing or the pattern is partly out of view")
    blobs.sort(key=lambda b: b[0][0])
    circles = [refine_circle(grey, c, r) for c, r in blobs]
    rows = np.array([e.centre_px[1] for e in circles])
    mean_axis = np.mean([np.mean(e.axes_px) for e in circles])
    if np.ptp(rows) > 0.5 * mean_axis + 0.1 * np.ptp([e.centre_px[0] for e in circles]):
        raise ValueError("the circles do not lie along one row: not the accuracy pattern")
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
    interleaved. A rig pairs them by its geometry instead (:func:`psvs.targets.pairing.pair_with_start`,
    :func:`psvs.accuracy.pattern_measure.measure_pattern`)."""
    circles = detect_circles(grey, count, max_diameter_px, min_area_px)
    return PatternDetection(circles[count:], circles[:count])
