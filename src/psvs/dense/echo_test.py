"""Does a complex image echo, and where, at which disparities? A test against chance with a stated false alarm.

A complex image C = (1 - s) L + s R shows each left-view point at x again at x - d (its right-view twin), so
a patch of C correlates with the patch d px to its left when its left-view content lies at disparity d. On an
image without echo (sensor noise, a blank wall, a texture whose twin is not in the frame) a patch correlates
with the patches along its row only by chance. The test asks, for every patch and every lag, whether the
correlation stands above what chance gives on *this* image, with a known false-alarm rate, using the image's
own statistics (no second run of the dense method, no threshold tuned to a camera).

**The statistic.** The image is split into bands (differences of Gaussians, :data:`BANDS_PX`), each band's
values divided by their local RMS (so every pixel weighs about the same: one strong edge cannot dominate a
patch). For square patches of :data:`CELL_PX` x m px (m in :data:`BLOCK_CELLS`, on a grid of one cell) and
every lag d, the normalised cross-correlation of the patch at x with the patch at x - d (on a build: the
left view's rectified grid against the right view's) is one number, rho(b, d), a sum over the patch's
pixels. Each patch's profile over the lags is centred on its median and divided by its spread (the 10-90 %
quantile range over 2.563, which is the standard deviation for a normal profile): z(b, d). A real echo is a
peak of several spreads at the patch's disparity; chance makes z of either sign.

**The null, from the same numbers.** Without echo, the correlation of a patch with an unrelated patch is as
likely to be negative as positive (the band-passed values have zero mean; NCC is odd in either patch), so
the negative side of the z values is chance's positive side mirrored, and an echo (always positive) never
touches it. Chance's tail is read there by peaks over threshold: with u the (k+1)-th largest of -z and beta
the mean excess of the k largest over u (its upper 2-sigma bound, beta (1 + 2 / sqrt(k))), the level that
n tests exceed with probability at most alpha is ``u + beta ln(k / alpha)`` (an exponential tail above u,
P(z > u + x) = (k / n) exp(-x / beta); exceeded by n tests alpha times in all: the union bound). The bands
and patch sizes are :data:`BANDS_PX` x :data:`BLOCK_CELLS` families, each at alpha / families.

**What is no twin.** A twin's echo in C correlates at s (1 - s) / ((1 - s)^2 + s^2) <= 1/2 whatever the split;
a patch that correlates with one along its row well beyond that copies itself there (stripes, a grating), so
its twin cannot be told and nothing in its cells counts as an echo (:data:`COPY_RHO`, :func:`copied_patches`).

**What chance is not.** At small lags a smooth texture correlates with itself (the image's own
autocorrelation, the same sign in every patch): lags below the first beyond which the median over all
patches stays within half a spread of zero are not tested (:func:`autocorrelation_lags`), as the dense
method does not search below :data:`~psvs.dense.params.MIN_LAG_PX`. A patch's profile needs at least
:data:`MIN_LAGS` lags with its twin patch inside the image to be standardised; narrower searches are
standardised over a wider span of lags (:func:`standardising_lags`), only the searched lags are judged.

Measured (bench/echo_test_check.py, docs/dense.md): on 600 images without echo of 0.05-1.3 MP (random pixels,
walls with sensor noise, blurred noise, vignetted walls saved as JPEG, shaded walls, demosaiced Bayer walls)
and random lag ranges, 1 judged an echo at alpha = 1 % (a JPEG wall); 599 of 600 planted echoes were found.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numba as nb
import numpy as np

from psvs.dense.fastmath import SAFE_MATH
from psvs.dense.params import MIN_LAG_PX

#: The false-alarm rate: the chance that an image without echo is judged to echo anywhere.
ALPHA = 0.01
#: px (at the judged level): the bands, C - blur(0.7) and blur(0.7) - blur(1.4) (differences of Gaussians).
BANDS_PX = (0.7, 1.4)
#: px: the side of a cell; patches are BLOCK_CELLS cells a side (powers of 2), one cell apart.
CELL_PX = 16
BLOCK_CELLS = (2, 4)
#: px: the local RMS that normalises each band is taken over this square.
RMS_WINDOW_PX = 7
#: The least number of lags a patch's profile is standardised over (a search over fewer is widened).
MIN_LAGS = 48
#: Exceedances of chance's (negative) tail that estimate its scale; more on a large test.
TAIL = 50
#: A negative z within this many lags of a positive one LOBE_RATIO times its size is that echo's side lobe.
LOBE_LAGS = 3
LOBE_RATIO = 2.0
#: A band of scale sigma px is not judged at lags below SHORT_LAGS x sigma: a patch of smooth texture still
#: correlates with itself there (its own autocorrelation, beyond what the image's median shows).
SHORT_LAGS = 6.0
#: The largest lag (px, judged level) at which the image's own autocorrelation is looked for.
AUTOCORRELATION_MAX_PX = 40
#: A patch whose correlation beyond chance peaks again, apart from its strongest peak's lobe, at this share of
#: it or more is ambiguous: its texture repeats along the row (stripes, bricks, a row of identical windows),
#: and which lag is its twin cannot be told from it (:func:`ambiguous_patches`).
RIVAL_RATIO = 0.5
#: By patch side in cells: a patch whose correlation with a patch along its row exceeds this is a copy of it,
#: not its twin. The complex image (1 - s) L + s R of a texture uncorrelated at other lags correlates with its
#: twin at s (1 - s) / ((1 - s)^2 + s^2) <= 1/2 at most (any split); a patch measures that to about 0.075 at 32
#: px a side and half that at 64 (band features correlated over a few px), so 0.9 and 0.75 lie 5 and 7 of those
#: beyond it. A texture that repeats along the row with a period p (stripes, a grating, a row of identical
#: parts) correlates with itself at every multiple of p, at 0.9-1 where it fills the patch and 0.7-0.85 where
#: the other view's texture lies over it, whatever its twins' disparity: its twin's echo is hidden, and each
#: multiple is as good an answer. (Measured, the largest of any patch: Fig. 5b, Middlebury Motorcycle and its
#: mirrored pair 0.51-0.80 at 32 px, 0.54-0.61 at 64 px; a card of 14 px stripes before a wall, its patches'
#: median 0.80-0.83; :func:`copied_patches`.)
COPY_RHO = {2: 0.9, 4: 0.75}


def band_features(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """The band of ``image`` (H, W) between scales sigma/2 and sigma (C - blur(sigma) for sigma below 1 px),
    divided by its RMS over :data:`RMS_WINDOW_PX`: float64 (H, W), about unit size where there is texture."""
    a = np.asarray(image, dtype=np.float32)
    fine = cv2.GaussianBlur(a, (0, 0), sigma_px / 2, borderType=cv2.BORDER_REFLECT) if sigma_px > 1.0 else a
    band = fine - cv2.GaussianBlur(a, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT)
    energy = cv2.boxFilter(band * band, -1, (RMS_WINDOW_PX, RMS_WINDOW_PX), borderType=cv2.BORDER_REFLECT)
    floor = 1e-3 * max(float(energy.mean()), 1e-20)
    return (band / np.sqrt(energy + floor)).astype(np.float64)


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _cell_sums(f, g2col, g, lags, cell, fg, gg):  # pragma: no cover - compiled
    """Per lag and cell whose twin lies wholly inside the image: sum f(x) g(x - d) into ``fg`` and sum
    g(x - d)^2 into ``gg`` (D, ny, nx); cells whose twin leaves the image stay 0. The products of a row of
    cells are summed down its rows first (elementwise along x, in vectors), then along each cell; ``g2col``
    (ny, W + 1) holds the running sums along x of g^2 summed down each row of cells."""
    w = f.shape[1]
    ny, nx = fg.shape[1], fg.shape[2]
    for k in nb.prange(len(lags)):
        d = lags[k]
        acc = np.empty(w, np.float64)
        for cy in range(ny):
            n = w - d
            a = acc[:n]
            a[:] = 0.0
            for y in range(cy * cell, cy * cell + cell):
                fr, gr = f[y, d:], g[y, :n]
                for i in range(n):
                    a[i] += fr[i] * gr[i]
            for cx in range(nx):
                x0 = cx * cell - d
                if x0 < 0:
                    continue
                s = 0.0
                for i in range(x0, x0 + cell):
                    s += a[i]
                fg[k, cy, cx] = s
                gg[k, cy, cx] = g2col[cy, x0 + cell] - g2col[cy, x0]
    return fg, gg


def _box(a: np.ndarray, m: int) -> np.ndarray:
    """Sums over m x m windows (m a power of 2) of the last two axes, one cell apart: (..., ny - m + 1,
    nx - m + 1), by halves: the sum of 2k x 2k is four sums of k x k, k apart."""
    k = 1
    while k < m:
        a = a[..., :-k, :-k] + a[..., k:, :-k] + a[..., :-k, k:] + a[..., k:, k:]
        k *= 2
    return a


@dataclass(frozen=True, eq=False)
class CellSums:
    """The sums behind every patch correlation of one band: ``fg``/``gg`` (D, ny, nx) sum f(x) g(x - d) and
    sum g(x - d)^2 over each cell (0 where the twin cell leaves the image), ``ff`` (ny, nx) sum f^2."""

    fg: np.ndarray
    gg: np.ndarray
    ff: np.ndarray


def cell_sums(f: np.ndarray, g: np.ndarray, lags: np.ndarray, cell: int = CELL_PX) -> CellSums:
    """:class:`CellSums` of ``f`` against ``g`` (H, W) over cells of ``cell`` px for each lag of ``lags`` (px)."""
    h, w = f.shape
    ny, nx = h // cell, w // cell
    lags = np.ascontiguousarray(lags, dtype=np.int64)
    f, g = np.ascontiguousarray(f, np.float64), np.ascontiguousarray(g, np.float64)
    g2col = np.zeros((ny, w + 1))
    g2col[:, 1:] = np.cumsum((g[:ny * cell] ** 2).reshape(ny, cell, w).sum(axis=1), axis=1)
    fg = np.zeros((len(lags), ny, nx))
    gg = np.zeros_like(fg)
    _cell_sums(f, g2col, g, lags, cell, fg, gg)
    ff = (f[:ny * cell, :nx * cell] ** 2).reshape(ny, cell, nx, cell).sum(axis=(1, 3))
    return CellSums(fg, gg, ff)


def patch_correlations(sums: CellSums, m: int) -> np.ndarray:
    """rho (D, ny - m + 1, nx - m + 1): the NCC of each patch of m x m cells with the patch d px to its left
    in the other image, for each lag of the :class:`CellSums`; NaN where the twin patch leaves the image or
    either patch has no texture."""
    inside = _box((sums.gg > 0).astype(np.float64), m) == m * m
    num, den = _box(sums.fg, m), _box(sums.gg, m) * _box(sums.ff[None], m)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(inside & (den > 0), num / np.sqrt(np.where(den > 0, den, 1.0)), np.nan)


@nb.njit(cache=True)
def _quantile(s, p):  # pragma: no cover - compiled
    """The p-quantile of a sorted 1-D array (the nearest rank)."""
    return s[min(s.shape[0] - 1, int(p * (s.shape[0] - 1) + 0.5))]


@nb.njit(cache=True, parallel=True)
def _standardise(rho, min_lags, z, spread):  # pragma: no cover - compiled
    d, n = rho.shape
    for j in nb.prange(n):
        v = rho[:, j]
        ok = np.isfinite(v)
        if ok.sum() < min_lags:
            continue
        s = np.sort(v[ok])
        med, sd = _quantile(s, 0.5), (_quantile(s, 0.9) - _quantile(s, 0.1)) / 2.563
        if sd <= 0:
            continue
        spread[j] = sd
        for k in range(d):
            if ok[k]:
                z[k, j] = (v[k] - med) / sd


def standardised(rho: np.ndarray, min_lags: int = MIN_LAGS) -> tuple[np.ndarray, np.ndarray]:
    """(z, spread): z (D, ...) of patch correlations ``rho`` (D, ...), each patch's profile over the lags
    centred on its median and divided by its spread, the 10-90 % range / 2.563 ((...), NaN for patches with
    fewer than ``min_lags`` finite lags or a flat profile, whose z are NaN too)."""
    flat = np.ascontiguousarray(rho.reshape(rho.shape[0], -1), dtype=np.float64)
    z = np.full_like(flat, np.nan)
    spread = np.full(flat.shape[1], np.nan)
    _standardise(flat, int(min_lags), z, spread)
    return z.reshape(rho.shape), spread.reshape(rho.shape[1:])


@nb.njit(cache=True, parallel=True)
def _lag_medians(rho, out):  # pragma: no cover - compiled
    for k in nb.prange(rho.shape[0]):
        v = rho[k]
        v = v[np.isfinite(v)]
        if v.size:
            out[k] = _quantile(np.sort(v), 0.5)


@dataclass(frozen=True)
class ChanceLevel:
    """Where chance's tail puts a family of n tests: ``threshold`` (z) is exceeded by chance with
    probability at most ``alpha`` in all; ``largest`` the largest z of chance's side (-z), ``scale`` the
    tail's scale beta (upper bound), ``tests`` n."""

    threshold: float
    largest: float
    scale: float
    tests: int


@nb.njit(cache=True, parallel=True)
def _chance_side(z, reach, ratio, out):  # pragma: no cover - compiled
    d, n = z.shape
    for j in nb.prange(n):
        for k in range(d):
            v = z[k, j]
            if not v < 0:
                continue
            lobe = False
            for i in range(max(0, k - reach), min(d, k + reach + 1)):
                if z[i, j] >= -ratio * v:
                    lobe = True
                    break
            if not lobe:
                out[k, j] = -v


def chance_side(z: np.ndarray) -> np.ndarray:
    """-z (D, ...) where z < 0 and is no side lobe of an echo (NaN elsewhere): a band-passed texture's
    correlation dips either side of its peak, so a value within :data:`LOBE_LAGS` lags of a positive one
    :data:`LOBE_RATIO` times its size, in the same patch, belongs to that peak, not to chance."""
    flat = np.ascontiguousarray(z.reshape(z.shape[0], -1))
    out = np.full_like(flat, np.nan)
    _chance_side(flat, LOBE_LAGS, LOBE_RATIO, out)
    return out.reshape(z.shape)


def chance_level(z: np.ndarray, alpha: float) -> ChanceLevel:
    """The level of a family of z tests (D, ...; NaN ignored) that chance exceeds with probability at
    most ``alpha``, from their negative side (module docstring, :func:`chance_side`): u + beta ln(k / alpha)."""
    v = z[np.isfinite(z)]
    neg = chance_side(z)
    neg = neg[np.isfinite(neg)]
    if neg.size < 2 * TAIL:
        return ChanceLevel(math.inf, float(neg.max(initial=0.0)), math.nan, int(v.size))
    k = max(TAIL, v.size // 500)
    k = min(k, neg.size - 1)
    top = np.sort(np.partition(neg, neg.size - k - 1)[neg.size - k - 1:])[::-1]
    u = float(top[k])
    beta = float(top[:k].mean() - u) * (1.0 + 2.0 / math.sqrt(k))
    return ChanceLevel(u + beta * math.log(k / alpha), float(top[0]), beta, int(v.size))


def autocorrelation_lags(rho: np.ndarray, spread: float, lags: np.ndarray) -> int:
    """The first lag (px) free of the image's own autocorrelation: scanning up from the first of ``lags`` (when
    it is within :data:`AUTOCORRELATION_MAX_PX`), the first where the median over all patches of ``rho`` (D,
    ...) is within half the patches' median ``spread`` of zero, or stops falling. (A smooth texture
    correlates with itself at small lags in every patch alike, a lobe falling from lag 1; an echo further up,
    even one that fills the image, is not touched.)"""
    if lags[0] > AUTOCORRELATION_MAX_PX:
        return int(lags[0])
    trend = np.full(rho.shape[0], np.nan)
    _lag_medians(np.ascontiguousarray(rho.reshape(rho.shape[0], -1)), trend)
    for k in range(len(lags)):
        bottom = k + 1 < len(lags) and trend[k + 1] >= trend[k]     # the lobe falling from lag 1 ends here
        if lags[k] > AUTOCORRELATION_MAX_PX or abs(trend[k]) <= 0.5 * spread or bottom:
            return int(lags[k])
    return int(lags[-1]) + 1


def standardising_lags(lo: int, hi: int, width: int) -> np.ndarray:
    """The lags (px) a search of lo..hi px is standardised over: lo..hi widened (downward first, then
    upward) to at least :data:`MIN_LAGS` where the image is wide enough; from 1 px when lo is within
    :data:`AUTOCORRELATION_MAX_PX` (:func:`autocorrelation_lags`), and then up to at least MIN_LAGS beyond
    that reach (what the autocorrelation takes away leaves enough)."""
    lo, hi = max(1, lo), min(hi, width - 1)
    if lo <= AUTOCORRELATION_MAX_PX:
        lo, least = 1, AUTOCORRELATION_MAX_PX + MIN_LAGS
    else:
        lo, least = max(1, lo - max(0, MIN_LAGS - (hi - lo + 1))), MIN_LAGS
    return np.arange(lo, min(width - 1, max(hi, lo + least - 1)) + 1)


def standardised_patches(sums: CellSums, m: int, sigma: float, lags: np.ndarray):
    """(z, first lag judged, rho) of the patches of m x m cells of one band (scale ``sigma`` px): their
    correlations rho (D, by, bx) (:func:`patch_correlations`) standardised (:func:`standardised`) and, when the
    band's short lags or the image's own autocorrelation (:func:`autocorrelation_lags`) reach past the first of
    ``lags``, standardised again without those lags (NaN in z and rho); None when no patch profile can be
    standardised."""
    rho = patch_correlations(sums, m)
    z, spread = standardised(rho)
    if not np.isfinite(spread).any():
        return None
    start = max(MIN_LAG_PX, math.ceil(SHORT_LAGS * sigma), autocorrelation_lags(rho, float(np.nanmedian(spread)), lags))
    if start > lags[0]:
        rho[lags < start] = np.nan
        z, _ = standardised(rho)
    return z, start, rho


def copied_patches(rho: np.ndarray, m: int) -> np.ndarray:
    """bool (...) of the patches of m x m cells whose correlations ``rho`` (D, ...: NaN ignored) exceed
    :data:`COPY_RHO` [m] at some lag: more than any twin's echo gives, so the texture repeats there along the
    row (a copy, not a twin). The standardised z cannot show it: a periodic profile's spread is as large as
    its peaks (a card of 14 px stripes before a textured wall peaked at z 1-2, and was trusted, answered at a
    multiple of its period, through the wall's region it joined)."""
    return (rho > COPY_RHO[m]).any(axis=0)          # (NaN compares false: a lag not judged copies nothing)


@dataclass(frozen=True, eq=False)
class EchoTest:
    """The test's outcome on one image (pair) at its judged level. ``echo`` (D, ny, nx) bool: lag k of
    ``lags`` echoes beyond chance in some patch covering cell (cy, cx) (any band, any patch size);
    ``lags`` (D,) px; ``cell_px``; ``strongest`` the largest z of any judged test relative to its family's
    threshold (> 1: an echo), with ``strongest_z``/``strongest_threshold`` and where it is
    (``strongest_at``: (u, v) px of the patch's centre, its side px, its lag px); ``first_lag`` the
    smallest lag judged (the autocorrelation's end); ``patches`` judged (patch, lag) tests in all;
    ``ambiguous`` (ny, nx) bool: cells that only patches echoing at two separate peaks cover
    (:func:`ambiguous_patches`: a repeating texture; not counted as echoes), and every cell a patch that
    copies itself along the row covers (:func:`copied_patches`), whatever other patches show there; those
    alone in ``copied`` (ny, nx) bool."""

    echo: np.ndarray
    lags: np.ndarray
    cell_px: int
    strongest: float
    strongest_z: float
    strongest_threshold: float
    strongest_at: tuple[float, float, int, int]
    first_lag: int
    tests: int
    ambiguous: np.ndarray
    copied: np.ndarray | None = None

    @property
    def echoes(self) -> bool:
        """Whether any patch echoes beyond chance."""
        return bool(self.echo.any())

    def covers_map(self, disparity: np.ndarray, keep: np.ndarray, scale: float, right: bool,
                   tol_px: float) -> np.ndarray:
        """Whether each ``keep`` pixel (u, v) of a disparity map (H, W, px) of the image ``scale`` times this
        level's size has an echoing lag within ``tol_px`` (px, this level) of its disparity d / scale in a patch
        that covers it at (u, v) / scale (a right-view map's pixel: at its left-view twin, (u + d) / scale):
        bool (H, W), False where d is not finite or the pixel lies outside the cells."""
        return _covers_map(np.ascontiguousarray(disparity), np.ascontiguousarray(keep, dtype=bool), self.echo,
                           np.asarray(self.lags, np.int64), self.cell_px, float(scale), bool(right), float(tol_px))


@nb.njit(cache=True, inline="always")
def _echo_near(echo, l0, l1, cy, cx, d, tol):  # pragma: no cover - compiled
    """Whether cell (cy, cx) (any integers) echoes at a lag within tol of d (finite)."""
    _, ny, nx = echo.shape
    if cy < 0 or cy >= ny or cx < 0 or cx >= nx:
        return False
    for lag in range(max(l0, int(math.ceil(d - tol))), min(l1, int(math.floor(d + tol))) + 1):
        if echo[lag - l0, cy, cx]:
            return True
    return False


@nb.njit(cache=True, parallel=True)
def _covers_map(disparity, keep, echo, lags, cell, scale, right, tol):  # noqa: PLR0913  # pragma: no cover
    h, w = disparity.shape
    out = np.zeros((h, w), np.bool_)
    for y in nb.prange(h):
        cy = int((y / scale) // cell)
        for x in range(w):
            if keep[y, x]:
                d = np.float64(disparity[y, x]) / scale
                if np.isfinite(d):
                    at = x / scale + (d if right else 0.0)
                    out[y, x] = _echo_near(echo, lags[0], lags[-1], cy, int(at // cell), d, tol)
    return out


@nb.njit(cache=True, parallel=True)
def _ambiguous(z, threshold, ratio, out):  # pragma: no cover - compiled
    d, n = z.shape
    for j in nb.prange(n):
        top, at = -np.inf, -1
        for k in range(d):
            if z[k, j] > top:
                top, at = z[k, j], k
        if not top > threshold:
            continue
        floor = ratio * top
        lo, hi = at, at                         # the strongest peak's lobe: where z stays above its share
        while lo > 0 and z[lo - 1, j] > floor:
            lo -= 1
        while hi < d - 1 and z[hi + 1, j] > floor:
            hi += 1
        rival = max(threshold, floor)
        for k in range(d):
            if (k < lo or k > hi) and z[k, j] > rival:
                out[j] = True
                break


def ambiguous_patches(z: np.ndarray, threshold: float, ratio: float = RIVAL_RATIO) -> np.ndarray:
    """bool (...) of the patches of ``z`` (D, ...: standardised correlations over the lags, NaN ignored) that
    exceed ``threshold`` at two separate peaks: beyond their strongest peak's lobe (the lags about it where z
    stays above ``ratio`` times the peak) z exceeds both the threshold and that share of the peak again. A
    repeating texture echoes at every multiple of its period, inside the searched range and beyond it alike."""
    flat = np.ascontiguousarray(z.reshape(z.shape[0], -1))
    out = np.zeros(flat.shape[1], np.bool_)
    _ambiguous(flat, float(threshold), float(ratio), out)
    return out.reshape(z.shape[1:])


def spread_to_cells(sig: np.ndarray, m: int) -> np.ndarray:
    """(D, ny - m + 1, nx - m + 1) patch flags -> (D, ny, nx): a cell is flagged when a patch covering it is."""
    d, by, bx = sig.shape
    out = np.zeros((d, by + m - 1, bx + m - 1), bool)
    for i in range(m):
        for j in range(m):
            out[:, i:i + by, j:j + bx] |= sig
    return out


def _repeats_to_the_right(mirrored: CellSums, m: int, short: np.ndarray, threshold: float, width: int) -> np.ndarray:
    """(ny, nx) bool: the cells covered by a patch of m x m cells whose correlation with what lies to its right
    (``mirrored``: the cell sums of the images flipped left to right, the two views swapped) peaks twice
    (:func:`ambiguous_patches` at ``threshold``), the ``short`` lags left out as in the left profile. In a
    complex image a texture echoes once either way (R(x) = L(x + d)); a repeating one at each period."""
    rho = patch_correlations(mirrored, m)
    rho[short] = np.nan
    z, _ = standardised(rho)
    flipped = spread_to_cells(ambiguous_patches(z, threshold)[None], m)[0]
    cell = CELL_PX
    out = np.zeros_like(flipped)
    for cx in range(flipped.shape[1]):           # flipped cell cx spans these columns of the image
        a, b = (width - (cx + 1) * cell) // cell, (width - cx * cell - 1) // cell
        for c in {a, b}:
            if 0 <= c < out.shape[1]:
                out[:, c] |= flipped[:, cx]
    return out


def echo_test(image: np.ndarray, d_min: float, d_max: float, image_right: np.ndarray | None = None,
              inside: tuple[np.ndarray, np.ndarray] | None = None, alpha: float = ALPHA) -> EchoTest:
    """Which lags of d_min..d_max px echo beyond chance, and where, in ``image`` (H, W) (on a build its left
    view's rectified grid, and ``image_right`` the right view's; ``inside`` the two grids' field masks,
    features outside them count as none). Module docstring; false alarm ``alpha`` for the whole image."""
    left = np.asarray(image, dtype=np.float64)
    right = left if image_right is None else np.asarray(image_right, dtype=np.float64)
    h, w = left.shape
    lags = standardising_lags(max(1, math.ceil(d_min)), math.floor(d_max), w)
    families = len(BANDS_PX) * len(BLOCK_CELLS)
    ny, nx = h // CELL_PX, w // CELL_PX
    echo = np.zeros((len(lags), ny, nx), bool)
    ambiguous, copied = np.zeros((ny, nx), bool), np.zeros((ny, nx), bool)
    best = (-math.inf, 0.0, 1.0, (0.0, 0.0, 0, 0))
    first, tests = int(lags[0]), 0
    judged = (lags >= math.ceil(d_min)) & (lags <= math.floor(d_max))
    for sigma in BANDS_PX:
        f, g = band_features(left, sigma), band_features(right, sigma)
        if inside is not None:
            f, g = np.where(inside[0], f, 0.0), np.where(inside[1], g, 0.0)
        sums = cell_sums(f, g, lags)
        mirrored = None            # each patch against what lies to its right: read only where something echoes
        for m in BLOCK_CELLS:
            if ny < m or nx < m:
                continue
            patches = standardised_patches(sums, m, sigma, lags)
            if patches is None:
                continue
            z, start, rho = patches
            first = max(first, start)
            level = chance_level(z, alpha / families)
            tests += level.tests
            zj = np.where(judged[:, None, None], z, np.nan)
            above = spread_to_cells((np.nan_to_num(zj, nan=-np.inf) > level.threshold).any(axis=0)[None], m)[0]
            # a repeat beyond the range counts, and one to the right (a patch near the left edge sees its
            # texture's copies there): the patch, or the cells a mirrored patch covers, say no echo
            amb = ambiguous_patches(z, level.threshold)
            copies = copied_patches(rho, m)
            amb_right = np.zeros_like(above)
            if above.any():        # a family without a judged test above chance has no echo to call ambiguous
                if mirrored is None:
                    mirrored = cell_sums(g[:, ::-1], f[:, ::-1], lags)
                amb_right = _repeats_to_the_right(mirrored, m, lags < start, level.threshold, w)
            ambiguous |= above & (spread_to_cells(amb[None], m)[0] | amb_right)
            copied |= spread_to_cells(copies[None], m)[0]
            zj[:, amb | copies] = np.nan
            if np.isfinite(zj).any():
                k, by, bx = np.unravel_index(np.nanargmax(zj), zj.shape)
                ratio = zj[k, by, bx] / level.threshold
                if ratio > best[0]:
                    side = m * CELL_PX
                    best = (ratio, float(zj[k, by, bx]), level.threshold,
                            (bx * CELL_PX + side / 2 - 0.5, by * CELL_PX + side / 2 - 0.5, side, int(lags[k])))
            echo |= spread_to_cells(np.nan_to_num(zj, nan=-np.inf) > level.threshold, m) & ~amb_right[None]
    return EchoTest(echo, lags, CELL_PX, float(best[0]), float(best[1]), float(best[2]), best[3], first, tests,
                    (ambiguous & ~echo.any(axis=0)) | copied, copied)
