"""Where to look for a point's twin: the disparities (px) of a working depth range, on the complex image's
own rows (the paper's geometry) or on the rows of a build's dual rectification (psvs.optics.rectify).

Depth range to disparity range is eq. (12) inverted, d = b f / (z + b/2) over the sensor's pitch
(:func:`psvs.optics.design.working_range`), widened by a margin for the plate's shift and the width of an
edge; on a build the rectified views' own f' b' / z'.
"""
from __future__ import annotations

import numpy as np

from psvs.optics.design import working_range
from psvs.optics.mirrors import check_in_front
from psvs.optics.rectify import Rectification, field_twins, needs_rectification, rectify
from psvs.optics.rig import Rig

#: Extra disparity margin (px) around the working range's ideal disparities (plate shift, edge width).
RANGE_MARGIN_PX = 4.0


def disparity_range(rig: Rig, near_mm: float, far_mm: float, rect: Rectification | None = None,
                    width_px: int | None = None) -> tuple[float, float]:
    """Disparities (px) of the working range near..far mm, widened by :data:`RANGE_MARGIN_PX` (near must lie beyond the
    front of the mirrors, :func:`psvs.optics.mirrors.check_in_front`); with ``rect``,
    rectified disparities f' b' / z' (z' from the views' centres along the rectified axis). With
    ``width_px`` (the searched image's width), the largest is cut at its last column; ValueError when even the
    smallest lies beyond it (no point of the range is seen by both views).

    Examples
    --------
    >>> from psvs import default_rig
    >>> lo, hi = disparity_range(default_rig(), 400.0, 1200.0)
    >>> round(lo, 1), round(hi, 1)
    (86.4, 255.1)
    """
    wr = working_range(rig, near_mm, far_mm)          # checks the range
    check_in_front(rig, near_mm)
    if rect is None:
        lo, hi = wr.disparity_px
    else:
        zc = 0.5 * (rect.centres_mm["left"] + rect.centres_mm["right"]) @ rect.rotation[2]
        lo, hi = (rect.camera_matrix[0, 0] * rect.baseline_mm / (z - zc) for z in (far_mm, near_mm))
    lo, hi = max(1.0, lo - RANGE_MARGIN_PX), hi + RANGE_MARGIN_PX
    if width_px is None:
        return lo, hi
    if lo >= width_px - 1.0:
        raise ValueError(f"at {near_mm:g}-{far_mm:g} mm the twins stand {lo:.0f}-{hi:.0f} px apart, beyond the "
                         f"{width_px} px wide image: no point of that range is seen by both views (a farther "
                         f"range, --near-mm/--far-mm)")
    return lo, min(hi, width_px - 1.0)


def working_disparities(rig: Rig, near_mm: float, far_mm: float,
                        rect: Rectification | None = None) -> tuple[float, float] | None:
    """The disparities (px) the working range near..far mm gives anywhere in the views' common field, traced
    exactly (the plate, the mirrors as built, the lens): (the least over the field at ``far_mm``, the largest
    at ``near_mm``), u_l - u_r on the complex image, or u'_l - u'_r on ``rect``'s grids. No margin: an answer
    outside this span is a depth outside the range (:func:`disparity_range` widens it to search). None when
    neither depth shows a point to both views (e.g. a range nearer than the views overlap).

    Points: :func:`psvs.optics.rectify.field_twins` of a 41 x 31 grid of the left view's pixels."""
    span = []
    for (lu, ru), far in zip(field_twins(rig, (float(far_mm), float(near_mm)), (41, 31)), (True, False),
                             strict=True):
        if rect is not None:
            lu, ru = rect.to_rectified(lu, "left"), rect.to_rectified(ru, "right")
        d = lu[:, 0] - ru[:, 0]
        d = d[np.isfinite(d)]
        if not len(d):
            return None
        span.append(float(d.min()) if far else float(d.max()))
    return span[0], span[1]


def rectification_for(rig: Rig, near_mm: float, far_mm: float) -> Rectification | None:
    """The rig's dual rectification over near..far mm (cached), or None where its own rows serve."""
    return rectify(rig, float(near_mm), float(far_mm)) if needs_rectification(rig) else None
