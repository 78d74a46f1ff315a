"""Echo outside the searched disparities: a surface whose twin lies beyond the asked range, and a texture that
repeats along its rows.

The dense method answers every pixel with a lag of the range it searched. A surface whose twin lies outside
that range (nearer than ``--near-mm``, beyond ``--far-mm``: a narrowed search, or a hand in front of the rig)
still gets an answer there, the lag its neighbourhood favours; on a smooth map those answers form consistent
regions, and a region that touches one anchored pixel (a patch on the boundary that echoes at the wall's lag
behind) would be trusted whole (an adversarial trial: ``--near-mm 1000 --far-mm 1200`` on a scene whose cards
stand at 580 mm trusted 51 % of the pixels, a fifth of them more than 10 % off in depth).

The test here asks, for each patch, where along the *whole* row its echo is strongest: the statistic,
standardisation and chance level of :func:`psvs.dense.echo_test.echo_test` over every lag the image allows
(one level coarser than the echo test's, which costs about what that test costs). A patch that echoes beyond
chance at a lag of the searched range (within :data:`EDGE_LAGS` of it) echoes *here*. One that does not, and
whose strongest correlation stands beyond chance outside the range, echoes *elsewhere*: above the range, or
below it down to :data:`BELOW` times its lower end (a surface up to about 1 / BELOW times as far as the far
end), it shows a surface the search could not reach; further below, at a lag short beside the range, it
*repeats*: a texture that repeats along the row (bricks of period p correlate with themselves at p, 2p ...,
and at some multiple inside the range: the method then answers the repeat, not the twin), or a surface far
beyond the range. A patch whose strongest echo lies just past an end (within :data:`EDGE_LAGS`, so it echoes
*here* too, but a whole lag or more past it) shows a surface the search stops short of: the method answers it
at the end's lag, or at a neighbouring surface's. Each patch size judges its own cells (a small patch on an
object sees it alone; a large one across the object's border sees the surface behind it too): a cell is
flagged when patches of one size echo elsewhere there and none of that size echoes here, and the cells beside
flagged cells are flagged too (the border that a patch also showing the range keeps; not the cells past an
end, where no patch of the size echoes most strongly inside the range). In a cell beyond the range or just
past an end nothing is trusted; in a repeating cell only a surface whose own echo anchors it there
(:mod:`psvs.dense.trust`: a region with an anchored pixel in the repeating cells; a consistent region grown in
from outside them is not). A repeating
texture whose repeats exceed chance at several lags is left to the echo test's own ambiguity rule. On an
image without echo a cell is flagged with probability :data:`ALPHA` at most, and flagging only takes trust
away.
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

__all__ = ["BELOW", "EDGE_LAGS", "Elsewhere", "echo_elsewhere"]

#: lags (at the test's level) within this of the searched range's ends count as inside it.
EDGE_LAGS = 2
#: Below the searched range, lags down to this share of its lower end show a surface beyond the far end (up to
#: about 1 / BELOW times as far); shorter lags a texture that repeats along the row (or a surface far beyond).
BELOW = 0.5
#: The least number of cells across (at the coarser level) for the test to run there; else at the given level.
MIN_CELLS = 8


@dataclass(frozen=True, eq=False)
class Elsewhere:
    """The outcome, on cells of ``cell_px`` px at the test's level (``scale`` times coarser than the image it
    was given), each (ny, nx) bool: ``cells`` that echo only outside the searched range (nothing in them is
    trusted) and ``repeating`` cells whose strongest echo is a short repeat along the row. ``strongest_lag_px``
    (px of the given image; NaN when no patch echoes outside the range) and ``strongest_z`` the strongest echo
    outside the range, ``threshold`` its family's chance level; ``period_px``, ``period_z`` and
    ``period_threshold`` the same of the strongest repeat, ``edge_lag_px``, ``edge_z`` and ``edge_threshold``
    of the strongest echo just outside the range that counts as inside it (within :data:`EDGE_LAGS`: a surface
    the search may not quite reach). ``past_ends`` (2, ny, nx): the cells whose patches echo most strongly a
    whole lag or more past the asked range's far end ([0], below its smallest disparity) or near end ([1]), within
    :data:`EDGE_LAGS`, and none of that size most strongly inside it: a surface just beyond the range, which the
    search answers at the end's lag (:mod:`psvs.dense.trust` trusts no answer there)."""

    cells: np.ndarray
    cell_px: int
    scale: float
    strongest_lag_px: float
    strongest_z: float
    threshold: float
    repeating: np.ndarray | None = None
    period_px: float = math.nan
    period_z: float = math.nan
    period_threshold: float = math.nan
    edge_lag_px: float = math.nan
    edge_z: float = math.nan
    edge_threshold: float = math.nan
    past_ends: np.ndarray | None = None

    @property
    def past_any(self) -> bool:
        """Whether some cell's strongest echo lies just past an end of the asked range (:attr:`past_ends`)."""
        return self.past_ends is not None and bool(self.past_ends.any())

    @property
    def any(self) -> bool:
        """Whether some cell echoes only outside the searched range."""
        return bool(self.cells.any())

    @property
    def repeats(self) -> bool:
        """Whether some cell's strongest echo is a short repeat along its row."""
        return self.repeating is not None and bool(self.repeating.any())


def _level(image, right, inside):
    """The images one level coarser (and their field masks), or as given when that level is too narrow."""
    if image.shape[1] // 2 < MIN_CELLS * CELL_PX or image.shape[0] // 2 < max(BLOCK_CELLS) * CELL_PX:
        return image, right, inside, 1.0
    shrink = None if inside is None else tuple(
        cv2.resize(m.astype(np.uint8), (image.shape[1] // 2, image.shape[0] // 2),
                   interpolation=cv2.INTER_NEAREST) > 0 for m in inside)
    return halved(image), None if right is None else halved(right), shrink, 2.0


@dataclass
class _Strongest:
    """The strongest echo of a class seen so far: z relative to its family's threshold, (z, lag), threshold."""
    ratio: float = -math.inf
    z: float = math.nan
    lag: float = math.nan
    threshold: float = math.nan

    def update(self, top: np.ndarray, lags: np.ndarray, at: np.ndarray, which: np.ndarray, threshold: float):
        """Take the strongest of the ``which`` patches (bool (ny', nx')) of one family (``top`` their strongest z,
        at index ``at`` of ``lags``; chance's ``threshold``) when it is stronger, relative to its threshold."""
        if which.any():
            k = np.flatnonzero(which.ravel())[np.argmax(top.ravel()[which.ravel()])]
            if top.ravel()[k] / threshold > self.ratio:
                self.ratio, self.z = top.ravel()[k] / threshold, float(top.ravel()[k])
                self.lag, self.threshold = float(lags[at.ravel()[k]]), threshold


def _family(sums, m: int, sigma: float, lags: np.ndarray, classes: tuple, alpha: float, strongest: tuple):
    """One band's patches of m x m cells: the cells they show echoing (here, above or just below the range,
    repeating), each (ny, nx) bool, or None when no patch profile can be standardised. ``classes``: the lags
    (bool (D,)) judged, outside the range, short, inside the range itself; ``strongest``: the
    :class:`_Strongest` of the outside, short and edge classes."""
    patches = standardised_patches(sums, m, sigma, lags)
    if patches is None:
        return None
    judged, outside, short, exact, past_far, past_near = classes
    z = patches[0]
    level = chance_level(z, alpha)
    filled = np.nan_to_num(z, nan=-np.inf)
    at = filled.argmax(axis=0)
    top = np.take_along_axis(filled, at[None], 0)[0]
    here = (filled[judged] > level.threshold).any(axis=0)
    clear = ~ambiguous_patches(z, level.threshold)
    away = (top > level.threshold) & ~here & clear
    out = []
    for which, best in zip((away & outside[at], away & short[at]), strongest[:2], strict=True):
        best.update(top, lags, at, which, level.threshold)
        out.append(spread_to_cells(which[None], m)[0])
    strongest[2].update(top, lags, at, (top > level.threshold) & judged[at] & ~exact[at], level.threshold)
    echoing = (top > level.threshold) & clear
    for which in (exact, past_far, past_near):      # where the strongest echo lies: in the range, just past it
        out.append(spread_to_cells((echoing & which[at])[None], m)[0])
    return spread_to_cells(here[None], m)[0], *out


def _widened(cells: np.ndarray) -> np.ndarray:
    """``cells`` and the cells beside them (the border a patch that also shows the range keeps)."""
    return cv2.dilate(cells.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0 if cells.any() else cells


def echo_elsewhere(image: np.ndarray, d_min: float, d_max: float, image_right: np.ndarray | None = None,
                   inside: tuple[np.ndarray, np.ndarray] | None = None, alpha: float = ALPHA,
                   asked: tuple[float, float] | None = None) -> Elsewhere:
    """Which cells of ``image`` (H, W; on a build its left view's rectified grid, ``image_right`` the right
    view's, ``inside`` their field masks) echo only outside the searched d_min..d_max px, which repeat along
    their rows, and which echo just past an end of the ``asked`` disparities (px of ``image``; default the
    searched ones) (module docstring); false alarm ``alpha`` for the whole image."""
    left = np.asarray(image, dtype=np.float64)
    right = left if image_right is None else np.asarray(image_right, dtype=np.float64)
    left, right, inside, scale = _level(left, right, inside)
    h, w = left.shape
    lags = np.arange(1, w - 1)
    lo, hi = d_min / scale - EDGE_LAGS, d_max / scale + EDGE_LAGS
    a_min, a_max = (d_min, d_max) if asked is None else asked
    a_lo, a_hi = a_min / scale - EDGE_LAGS, a_max / scale + EDGE_LAGS
    classes = ((lags >= lo) & (lags <= hi), (lags > hi) | ((lags < lo) & (lags >= BELOW * d_min / scale)),
               lags < min(lo, BELOW * d_min / scale), (lags >= a_min / scale) & (lags <= a_max / scale),
               (lags >= a_lo) & (lags <= math.floor(a_min / scale) - 1),     # a whole lag or more past an end
               (lags <= a_hi) & (lags >= math.ceil(a_max / scale) + 1))
    ny, nx = h // CELL_PX, w // CELL_PX
    seen = {m: np.zeros((6, ny, nx), bool) for m in BLOCK_CELLS}
    strongest = (_Strongest(), _Strongest(), _Strongest())
    families = len(BANDS_PX) * len(BLOCK_CELLS)
    for sigma in BANDS_PX:
        f, g = band_features(left, sigma), band_features(right, sigma)
        if inside is not None:
            f, g = np.where(inside[0], f, 0.0), np.where(inside[1], g, 0.0)
        sums = cell_sums(f, g, lags)
        for m in BLOCK_CELLS:
            if ny < m or nx < m:
                continue
            out = _family(sums, m, sigma, lags, classes, alpha / families, strongest)
            if out is not None:
                seen[m] |= np.stack(out)
    away, repeating = np.zeros((ny, nx), bool), np.zeros((ny, nx), bool)
    past = np.zeros((2, ny, nx), bool)
    for here, beyond, short, inside_range, past_far, past_near in seen.values():   # each patch size its own cells
        away |= beyond & ~here
        repeating |= short & ~here
        past |= np.stack((past_far, past_near)) & ~inside_range
    a, r, e = strongest
    return Elsewhere(_widened(away), CELL_PX, scale, a.lag * scale, a.z, a.threshold, _widened(repeating),
                     r.lag * scale, r.z, r.threshold, e.lag * scale, e.z, e.threshold, past)
