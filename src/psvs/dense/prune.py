"""Range pruning: the lags the default mode searches, from a coarse pass over the whole range.

A scene rarely fills a rig's whole working range (a wall fills one disparity), and the full-resolution
search costs in proportion to the lags it searches. :func:`psvs.dense.disparity.dense_disparity` therefore
first runs the coarse pass (:data:`psvs.dense.params.COARSE`, the fast mode) over the range asked for, and
searches at full resolution only what :func:`pruned_range` keeps of it, :func:`widened` to at least
:data:`MIN_PRUNED_LAGS` px. Ranges that :func:`worth_pruning` rejects are searched whole.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from psvs.dense.params import MIN_LAG_PX

if TYPE_CHECKING:
    from psvs.dense.disparity import DenseResult

#: px: ranges of at most twice this many lags are searched whole, and none is pruned below it.
MIN_PRUNED_LAGS = 8
#: The coarse pass's support for a disparity: at least this share of its pixels (and PRUNE_MIN_PX of them) with
#: a consistent answer within 1 px of it; the pruned range keeps PRUNE_MARGIN_PX (full-resolution px) and
#: PRUNE_MARGIN_SHARE of its span beyond the outermost supported disparities.
PRUNE_MIN_SHARE = 2e-4
PRUNE_MIN_PX = 8
PRUNE_MARGIN_PX = 4.0
PRUNE_MARGIN_SHARE = 0.1


def worth_pruning(d_min: float, d_max: float) -> bool:
    """Whether the range d_min..d_max (px) holds more than 2·:data:`MIN_PRUNED_LAGS` whole-px lags to search
    (from :data:`~psvs.dense.params.MIN_LAG_PX` up), so that a coarse pass may narrow it; a narrower one is
    searched whole (and the coarse scale would have at most 4 lags to search in it)."""
    return math.floor(d_max) - max(MIN_LAG_PX, math.ceil(d_min)) > 2 * MIN_PRUNED_LAGS


def pruned_range(coarse: DenseResult, d_min: float, d_max: float, n_pixels: int) -> tuple[float, float]:
    """The part of d_min..d_max (px) that the coarse pass ``coarse`` (both maps, full-resolution px) finds
    in the scene: from its smallest to its largest well-supported consistent disparity (a confidence
    above 0), widened by a margin; the whole range when it finds none. ``n_pixels``: the image's pixel
    count, for the support's share."""
    d = np.concatenate([coarse.disparity_left[coarse.confidence_left > 0],
                        coarse.disparity_right[coarse.confidence_right > 0]])
    d = d[np.isfinite(d)]
    if d.size == 0:
        return d_min, d_max
    counts = np.bincount(np.clip(np.rint(d).astype(np.int64), 0, None))
    support = np.convolve(counts, np.ones(3, np.int64), mode="same")      # within 1 px
    found = np.flatnonzero(support >= max(PRUNE_MIN_PX, PRUNE_MIN_SHARE * n_pixels))
    if found.size == 0:
        return d_min, d_max
    lo, hi = float(found[0]), float(found[-1])
    margin = PRUNE_MARGIN_PX + PRUNE_MARGIN_SHARE * (hi - lo)
    return max(d_min, lo - margin), min(d_max, hi + margin)


def widened(lo: float, hi: float, d_min: float, d_max: float) -> tuple[float, float]:
    """lo..hi (px, inside d_min..d_max) widened about its middle to at least :data:`MIN_PRUNED_LAGS` px,
    shifted back inside d_min..d_max where it would stick out (one depth near an end of the range)."""
    short = MIN_PRUNED_LAGS - (hi - lo)
    if short > 0:
        lo, hi = lo - short / 2, hi + short / 2
        lo, hi = (max(d_min, lo - max(0.0, hi - d_max)), min(d_max, hi + max(0.0, d_min - lo)))
    return lo, hi
