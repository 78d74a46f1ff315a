"""Echo outside the searched disparities: a surface whose twin lies beyond the asked range.

The dense method answers every pixel with a lag of the range it searched. A surface whose twin lies outside
that range (nearer than ``--near-mm``, beyond ``--far-mm``: a narrowed search, or a hand in front of the rig)
still gets an answer there, the lag its neighbourhood favours; on a smooth map those answers form consistent
regions, and a region that touches one anchored pixel (a patch on the boundary that echoes at the wall's lag
behind) would be trusted whole (an adversarial trial: ``--near-mm 1000 --far-mm 1200`` on a scene whose cards
stand at 580 mm trusted 51 % of the pixels, a fifth of them more than 10 % off in depth).

The test here asks, for each patch, where along the *whole* row its echo is strongest: the statistic,
standardisation and chance level of :func:`psvs.dense.echo_test.echo_test` over every lag the image allows
(one level coarser than the echo test's, which costs about what that test costs). A patch whose strongest
correlation stands beyond chance at a lag outside the searched range (by more than :data:`EDGE_LAGS`) echoes
*elsewhere*; one whose strongest stands beyond chance inside it echoes *here*. A cell covered by a patch that
echoes elsewhere and by none that echoes here shows a surface the search could not reach: no answer in it, or
in the cells beside it (a patch that also shows the surface in the range keeps its cells, so the surface's
border would stay), is trusted, whatever region it belongs to. Below the range only lags down to
:data:`BELOW` times its lower end are looked at: at smaller lags a texture repeating along the row correlates
with itself. A repeating texture (peaks at several lags) is left to the echo
test's own ambiguity rule. On an image without echo a cell is flagged with probability :data:`ALPHA` at most,
and flagging only takes trust away.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from psvs.dense.echo_test import (
    ALPHA,
    BANDS_PX,
    BLOCK_CELLS,
    CELL_PX,
    ambiguous_patches,
    band_features,
    cell_sums,
    chance_level,
    spread_to_cells,
    standardised_patches,
)
from psvs.dense.pyramid import halved

__all__ = ["EDGE_LAGS", "Elsewhere", "echo_elsewhere"]

#: lags (at the test's level) within this of the searched range's ends count as inside it.
EDGE_LAGS = 2
#: Below the searched range only lags down to this share of its lower end count (surfaces up to about 1 / BELOW
#: times as far as its far end): at smaller lags a texture that repeats along the row correlates with itself
#: (each rectified grid samples the complex image, both views in it: bricks of period p show at lags p, 2p ...).
BELOW = 0.5
#: The least number of cells across (at the coarser level) for the test to run there; else at the given level.
MIN_CELLS = 8


@dataclass(frozen=True, eq=False)
class Elsewhere:
    """The outcome: ``cells`` (ny, nx) bool, the cells of ``cell_px`` px (at the test's level, ``scale`` times
    coarser than the image it was given) that only patches echoing outside the searched range cover;
    ``strongest_lag_px`` (px of the given image; NaN when no patch echoes elsewhere) and ``strongest_z`` the
    strongest such echo, ``threshold`` its family's chance level."""

    cells: np.ndarray
    cell_px: int
    scale: float
    strongest_lag_px: float
    strongest_z: float
    threshold: float

    @property
    def any(self) -> bool:
        """Whether some cell echoes only outside the searched range."""
        return bool(self.cells.any())


def _level(image, right, inside):
    """The images one level coarser (and their field masks), or as given when that level is too narrow."""
    if image.shape[1] // 2 < MIN_CELLS * CELL_PX or image.shape[0] // 2 < max(BLOCK_CELLS) * CELL_PX:
        return image, right, inside, 1.0
    shrink = None if inside is None else tuple(
        cv2.resize(m.astype(np.uint8), (image.shape[1] // 2, image.shape[0] // 2),
                   interpolation=cv2.INTER_NEAREST) > 0 for m in inside)
    return halved(image), None if right is None else halved(right), shrink, 2.0


def _family(sums, m: int, sigma: float, lags: np.ndarray, judged: np.ndarray, outside: np.ndarray,
            alpha: float):
    """One band's patches of m x m cells: (cells echoing here (strongest at a ``judged`` lag), cells echoing
    elsewhere (strongest at an ``outside`` lag), (z, lag) of the strongest elsewhere, threshold), or None when
    no patch profile can be standardised."""
    patches = standardised_patches(sums, m, sigma, lags)
    if patches is None:
        return None
    z = patches[0]
    level = chance_level(z, alpha)
    filled = np.nan_to_num(z, nan=-np.inf)
    at = filled.argmax(axis=0)
    top = np.take_along_axis(filled, at[None], 0)[0]
    echoes = (top > level.threshold) & ~ambiguous_patches(z, level.threshold)
    inside = judged[at]
    here = spread_to_cells((echoes & inside)[None], m)[0]
    away = echoes & outside[at]
    strongest = (math.nan, math.nan)
    if away.any():
        k = np.flatnonzero(away.ravel())[np.argmax(top.ravel()[away.ravel()])]
        strongest = (float(top.ravel()[k]), float(lags[at.ravel()[k]]))
    return here, spread_to_cells(away[None], m)[0], strongest, level.threshold


def echo_elsewhere(image: np.ndarray, d_min: float, d_max: float, image_right: np.ndarray | None = None,
                   inside: tuple[np.ndarray, np.ndarray] | None = None, alpha: float = ALPHA) -> Elsewhere:
    """Which cells of ``image`` (H, W; on a build its left view's rectified grid, ``image_right`` the right
    view's, ``inside`` their field masks) echo only outside d_min..d_max px (module docstring); false alarm
    ``alpha`` for the whole image."""
    left = np.asarray(image, dtype=np.float64)
    right = left if image_right is None else np.asarray(image_right, dtype=np.float64)
    left, right, inside, scale = _level(left, right, inside)
    h, w = left.shape
    lags = np.arange(1, w - 1)
    lo, hi = d_min / scale - EDGE_LAGS, d_max / scale + EDGE_LAGS
    judged = (lags >= lo) & (lags <= hi)
    outside = (lags > hi) | ((lags < lo) & (lags >= BELOW * d_min / scale))
    ny, nx = h // CELL_PX, w // CELL_PX
    here, away = np.zeros((ny, nx), bool), np.zeros((ny, nx), bool)
    best, strongest, threshold = -math.inf, (math.nan, math.nan), math.nan
    families = len(BANDS_PX) * len(BLOCK_CELLS)
    for sigma in BANDS_PX:
        f, g = band_features(left, sigma), band_features(right, sigma)
        if inside is not None:
            f, g = np.where(inside[0], f, 0.0), np.where(inside[1], g, 0.0)
        sums = cell_sums(f, g, lags)
        for m in BLOCK_CELLS:
            if ny < m or nx < m:
                continue
            out = _family(sums, m, sigma, lags, judged, outside, alpha / families)
            if out is None:
                continue
            here |= out[0]
            away |= out[1]
            if math.isfinite(out[2][0]) and out[2][0] / out[3] > best:
                best, strongest, threshold = out[2][0] / out[3], out[2], out[3]
    away = away & ~here
    if away.any():      # and the cells beside them: the border a patch that also shows the range keeps
        away = cv2.dilate(away.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return Elsewhere(away, CELL_PX, scale, strongest[1] * scale, strongest[0], threshold)
