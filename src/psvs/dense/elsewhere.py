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
texture whose repeats exceed chance at several lags is left to the echo test's own ambiguity rule. A texture
that repeats every P px with P above the range (wallpaper, tiles) echoes in the range at its twin's lag d and
at its mirror P - d alike: a patch whose strongest echo lies above the range or in it and which echoes at two
other lags of it adding up to that one is *mirrored* (:func:`mirrored_patches`), and like a periodic cell
nothing in its cells, nor in a region reaching them, is trusted. On an image without echo a cell is flagged
with probability :data:`ALPHA` at most, and flagging only takes trust away.
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
    search answers at the end's lag (:mod:`psvs.dense.trust` trusts no answer there). ``periodic`` (ny, nx): the
    cells of patches that echo at every multiple of one period they can see, up to three, their strongest echo
    in the range among them (:func:`periodic_patches`: a texture that repeats every p px, whose echo in the
    range is its repeat, not its twin; nothing there is trusted, nor in a region reaching it), ``periodic_px``,
    ``periodic_z`` and ``periodic_threshold`` the strongest such repeat; ``mirrored`` (ny, nx): the cells of
    patches whose echoes in the range mirror a repeat above it (:func:`mirrored_patches`)."""

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
    periodic: np.ndarray | None = None
    periodic_px: float = math.nan
    periodic_z: float = math.nan
    periodic_threshold: float = math.nan
    mirrored: np.ndarray | None = None

    @property
    def mirrored_any(self) -> bool:
        """Whether some cell echoes at two lags of the range that mirror a repeat above it (:attr:`mirrored`)."""
        return self.mirrored is not None and bool(self.mirrored.any())

    @property
    def periodic_any(self) -> bool:
        """Whether some cell's echo in the range is a multiple of a shorter repeat (:attr:`periodic`)."""
        return self.periodic is not None and bool(self.periodic.any())

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


#: A lag lies on the comb of a period p when within this many lags, plus half a lag for each multiple k (p is
#: read to the nearest lag), of k p.
PERIODIC_TOL_LAGS = 1.0
#: The least number of multiples of one period (p, 2p, 3p, ...) at which a patch must echo for its texture to
#: repeat, of those its row lets it see (at least 2): two surfaces in one patch, one at about twice the other's
#: disparity, make two.
PERIODIC_MULTIPLES = 3
#: Multiples counted (beyond: the row's end).
_MAX_MULTIPLE = 24


def periodic_patches(z: np.ndarray, threshold: float, judged: np.ndarray,
                     lags: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Patches whose echo in the searched range is a repeat: each echoes beyond ``threshold`` at
    :data:`PERIODIC_MULTIPLES` or more multiples k p of one period p (within :data:`PERIODIC_TOL_LAGS` + k / 2
    lags; p its shortest echoing lag), or at each of the two it can see (near the image's edge), its strongest
    echo in the range (``judged``, bool (D,)) among them. A wall of a texture that repeats every p px (a fence,
    blinds, a tiled facade) makes a complex image that repeats every p px, whatever its twins' disparity: its
    patches correlate fully at p, 2p, ..., and the twin's own
    echo, halved by the other view, stands below those (an adversarial trial: walls at 800 mm repeating every
    40-90 px were trusted on 9-70 % of the frame, 60-100 % of it 2-27 % off). A texture that does not repeat
    echoes at its twin's lag; a patch across two surfaces at both (a card at 96 px before a wall at 45 px: two
    lags in a ratio of about 2, not three multiples). ``z`` (D, ny, nx) the patches' standardised correlations
    (NaN where not judged: the image's own autocorrelation), ``lags`` (D,). Returns (periodic (ny, nx) bool,
    p (ny, nx) lags, the z of the strongest echo on the comb (ny, nx))."""
    filled = np.nan_to_num(z, nan=-np.inf)
    ny, nx = filled.shape[1:]
    lag = lags.astype(float)
    inside = np.flatnonzero(judged)
    at = filled[inside].argmax(axis=0)
    strongest = inside[at]                                       # (ny, nx) index of the strongest lag in range
    strong = np.take_along_axis(filled[inside], at[None], 0)[0] > threshold
    echo = filled > threshold
    p = np.where(echo.any(axis=0), lag[echo.argmax(axis=0)], np.inf)    # the shortest echoing lag
    di, yi, xi = np.nonzero(echo)                                 # the echoes on p's comb: k p, k >= 1
    k = np.rint(lag[di] / p[yi, xi])
    on = (k >= 1) & (np.abs(lag[di] - k * p[yi, xi]) <= PERIODIC_TOL_LAGS + 0.5 * k)
    di, yi, xi, k = di[on], yi[on], xi[on], k[on].astype(np.int64)
    cell = yi * nx + xi
    span = _MAX_MULTIPLE + 1
    multiples = np.bincount(np.unique(cell * span + np.minimum(k, _MAX_MULTIPLE)) // span,
                            minlength=ny * nx).reshape(ny, nx)
    strongest_on = np.zeros(ny * nx, bool)
    strongest_on[cell[di == strongest[yi, xi]]] = True
    z_on = np.full(ny * nx, -np.inf)
    np.maximum.at(z_on, cell, filled[di, yi, xi])
    finite = np.isfinite(z)                 # the lags the patch can see: from its first to its last judged one
    first = lag[finite.argmax(axis=0)]
    last = lag[len(lag) - 1 - finite[::-1].argmax(axis=0)]
    with np.errstate(invalid="ignore"):
        visible = np.where(np.isfinite(p), np.floor(last / p) - np.ceil(first / p) + 1, 0)
    periodic = (strong & strongest_on.reshape(ny, nx) & (multiples >= np.minimum(visible, PERIODIC_MULTIPLES))
                & (multiples >= 2))
    return periodic, np.where(np.isfinite(p), p, np.nan), z_on.reshape(ny, nx)


#: lags: how near a + b must come to the strongest echo's lag P for two echoes a, b in the range to be its mirror
#: pair (P read to the nearest lag, each of a and b too).
MIRROR_TOL_LAGS = 1


def mirrored_patches(z: np.ndarray, threshold: float, judged: np.ndarray, above: np.ndarray,
                     lags: np.ndarray) -> np.ndarray:
    """Patches whose strongest echo lies above the searched range or in it, at P, and which echo beyond
    ``threshold`` at two lags a and P - a of the range (within :data:`MIRROR_TOL_LAGS`, and apart by more than
    twice that: a lag at P / 2 is its own mirror, no rival): a texture that repeats every P px along the row, P
    beyond the range or near its top. Its complex image echoes at the twin's lag d and at P - d alike (the left view
    against the right view's next repeat), and the method may answer either (an adversarial trial: a wall of
    wallpaper repeating every 212 mm at 800 mm, P 282 px against a range up to 258, answered at P - d = 148 px
    for 134 on 97 % of the pixels trusted, 9.4 % short). ``z`` (D, ny, nx) standardised correlations (NaN not
    judged), ``judged``/``above`` (D,) bool the lags of the range and above it, ``lags`` (D,) consecutive.
    Returns (ny, nx) bool."""
    filled = np.nan_to_num(z, nan=-np.inf)
    at = filled.argmax(axis=0)
    top = np.take_along_axis(filled, at[None], 0)[0]
    candidate = (top > threshold) & (above[at] | judged[at])
    out = np.zeros(candidate.shape, bool)
    if not candidate.any():
        return out
    echo = (filled > threshold) & judged[:, None, None]           # (D, ny, nx): echoes in the range
    yi, xi = np.nonzero(candidate)
    p = lags[at[yi, xi]]                                           # (n,) each candidate's P
    ia = np.flatnonzero(judged)                                    # the range's lags, as indices
    a = lags[ia][:, None]                                          # (Din, 1) the range's lags
    at_a = echo[ia][:, yi, xi]                                     # (Din, n) whether each candidate echoes at a
    rows, cols = np.broadcast_to(yi, (len(ia), len(yi))), np.broadcast_to(xi, (len(ia), len(xi)))
    for t in range(-MIRROR_TOL_LAGS, MIRROR_TOL_LAGS + 1):
        jb = p[None, :] - a + t - lags[0]                          # (Din, n): the index of P - a (+ t)
        # a lag that is its own mirror (a = P / 2: the twin at half the repeat) is no rival
        ok = (jb >= 0) & (jb < len(lags)) & (np.abs(jb + lags[0] - a) > 2 * MIRROR_TOL_LAGS)
        mirror = np.zeros(jb.shape, bool)
        mirror[ok] = echo[jb[ok], rows[ok], cols[ok]]
        out[yi, xi] |= (at_a & mirror).any(axis=0)
    return out


def _family(sums, m: int, sigma: float, lags: np.ndarray, classes: tuple, alpha: float, strongest: tuple):
    """One band's patches of m x m cells: the cells they show echoing (here, above or just below the range,
    repeating), each (ny, nx) bool, or None when no patch profile can be standardised. ``classes``: the lags
    (bool (D,)) judged, outside the range, short, inside the range itself; ``strongest``: the
    :class:`_Strongest` of the outside, short and edge classes."""
    patches = standardised_patches(sums, m, sigma, lags)
    if patches is None:
        return None
    judged, outside, short, exact, past_far, past_near, above = classes
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
    periodic, period, z_period = periodic_patches(z, level.threshold, judged, lags)
    strongest[3].update(z_period, period.ravel(), np.arange(period.size).reshape(period.shape), periodic,
                        level.threshold)
    out.append(spread_to_cells(periodic[None], m)[0])
    out.append(spread_to_cells(mirrored_patches(z, level.threshold, judged, above, lags)[None], m)[0])
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
               (lags <= a_hi) & (lags >= math.ceil(a_max / scale) + 1), lags > hi)
    ny, nx = h // CELL_PX, w // CELL_PX
    seen = {m: np.zeros((8, ny, nx), bool) for m in BLOCK_CELLS}
    strongest = (_Strongest(), _Strongest(), _Strongest(), _Strongest())
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
    away, repeating, periodic, mirrored = (np.zeros((ny, nx), bool) for _ in range(4))
    past = np.zeros((2, ny, nx), bool)
    for here, beyond, short, inside_range, past_far, past_near, cyclic, mirror in seen.values():   # each size its own
        away |= beyond & ~here
        repeating |= short & ~here
        past |= np.stack((past_far, past_near)) & ~inside_range
        periodic |= cyclic
        mirrored |= mirror
    a, r, e, c = strongest
    return Elsewhere(_widened(away), CELL_PX, scale, a.lag * scale, a.z, a.threshold, _widened(repeating),
                     r.lag * scale, r.z, r.threshold, e.lag * scale, e.z, e.threshold, past, _widened(periodic),
                     c.lag * scale, c.z, c.threshold, _widened(mirrored))
