"""How far each twin stands off its row, read off one ordinary frame through a calibration (docs/health.md).

A calibrated rig's dual rectification (docs/optics.md) puts every scene point's two images on the same row
of the left and the right view's rectified grids. A mirror that moved since (a knock, glue creeping) moves
one view's image across its rows: its twin now stands a few tenths of a pixel or more above or below. The
frame is resampled on both grids (:func:`psvs.dense.build.rectified_images`; the complex image itself on
the paper's geometry) and band-passed (a difference of Gaussians: the scene's shading and the lens's
fall-off do not correlate), then cut into square tiles on the left grid (overlapping by half). Each tile is correlated
(normalised cross-correlation, OpenCV's ``matchTemplate``) with the right grid over the working range's
disparities along its row and :func:`reach_px` rows either side; the peak's row, refined by a quadratic
through its 3 x 3 neighbourhood, is the tile's row offset (right twin's row minus the left's, px).

**Tested against chance, tile by tile.** A tile's peak must stand :data:`NULL_MARGIN` above the best
correlation the same tile finds in :data:`NULLS` bands of rows far from its own (where no twin can be, so
whatever peak they give is what its texture gives by chance), stand above its best match in its own search
away from its peak (at another disparity, more than the band-pass's coarse sigma off it, on the peak's rows) by
:data:`UNIQUE_SHARE` of that margin (a texture that repeats along the rows, bricks or stripes, matches almost
as well a period away: it tells no twin), stand above its best match on rows away from its peak's (each row's best
over the disparities, more than that sigma off the peak's row) by the same share (a texture that runs along
one direction, a seam's edges or a groove, matches along a ridge: shifted along itself it matches as well
on other rows at other disparities, and tells no row: the aperture problem), on a build its own texture must not
repeat on its own grid as strongly as its twin matches (:func:`_own_repeat`: a checkerboard), its texture must
stand above the sensor's
noise (:data:`MIN_TEXTURE_DN`), and the peak must be a peak (a negative-definite quadratic, inside the
searched rows). A tile whose best peak lies on the searched rows' edge is counted apart: its twin may be
farther off than the search reaches.
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from psvs._threads import pool_size
from psvs.dense.build import rectified_images
from psvs.dense.rig_cache import rectification
from psvs.health.plate_shift import rig_row_offsets
from psvs.optics.illumination import flat_field
from psvs.optics.rectify import Rectification
from psvs.optics.rig import Rig
from psvs.optics.search_range import disparity_range

#: Rows searched either side of a twin's nominal row, as an angle through the lens: a mirror knocked by
#: 0.25 deg moves its view's rows by about twice that. When too few tiles are found within it, the check
#: searches again FAR_REACH_DEG (psvs.health.check).
REACH_DEG = 0.5
FAR_REACH_DEG = 2.0
#: Tiles from which a frame's are read on two threads (a quick look at 36 on a 1440 x 1080 build: 122 ms on one
#: thread, 95 on two, the rest its resampling); a rolling check's few per frame stay on the caller's.
THREADED_TILES = 16
#: A tile's side is the rectified grid's shorter side over this, within TILE_PX (a 640 x 480 frame: 64 px).
TILES_ACROSS = 8
TILE_PX = (48, 128)
#: Bands of rows far from a tile's own searched for its chance peak, and how far above it its peak must be.
NULLS = 4
NULL_MARGIN = 0.05
#: A tile's peak must stand above its best match elsewhere in its own search (off the peak's lobe) by this
#: share of its margin over chance (a texture that repeats along the rows matches almost as well a period away).
UNIQUE_SHARE = 0.5
#: A tile's band-passed grey levels must spread this much (DN, standard deviation): above the sensor's noise.
MIN_TEXTURE_DN = 1.0
#: The band-pass: a difference of Gaussians of these sigmas (px).
BAND_SIGMAS_PX = (1.0, 4.0)
#: px: the smallest lag a tile's twin is searched at, twice the band-pass's coarse sigma. Nearer, a tile's own
#: correlation peak (on the paper's geometry both grids are the complex image) stands beside its twin's and
#: reads as a texture that repeats (an adversarial trial: a wall of noise at 700 mm checked with --far-mm
#: 20000, 5 px its smallest disparity, was "cannot judge: the texture repeats along the rows").
MIN_LAG_PX = 2.0 * BAND_SIGMAS_PX[1]


@dataclass(frozen=True)
class FrameTiles:
    """One frame's tiles on the left grid: ``centre_px`` (n, 2) (u', v') of each tile's centre, ``offset_px``
    (n,) its twin's row offset and ``disparity_px`` (n,) its disparity (NaN where not read), ``score`` (n,)
    its peak's correlation and ``chance`` (n,) the best its texture gave by chance, ``accepted`` (n,) the
    tiles that pass the chance test, ``at_edge`` (n,) those whose best peak lay on the searched rows' edge,
    ``repeating`` (n,) those above chance that match almost as well away from their peak along the rows, or
    on a build whose own texture repeats as strongly as their twin matches (a repeating texture: not
    accepted), ``ridged`` (n,) those above chance, not repeating, that match almost as well on other rows (a
    texture running along one direction: not accepted); ``places_px`` (m, 2) the centres
    of all the frame's tiles (the field a judgement speaks for); ``size_px`` a tile's side, ``reach_px`` the
    rows searched either side, ``grid_shape`` (H', W'), ``rect`` the rectification read through (None: the
    paper's geometry), ``of_tiles`` how many tiles the whole frame holds (these may be a subset of them),
    ``focal_px`` the grid's focal length (px, the shorter axis's; None: not known, and the field's curvature
    is not bounded by what a turned view can make, psvs.health.field), ``expected_px`` (n,) the offset the rig
    itself makes at each accepted tile (the plate's row shift on the paper's geometry,
    :func:`psvs.health.plate_shift.rig_row_offsets`; None: none, a build's rectified grids)."""

    centre_px: np.ndarray
    offset_px: np.ndarray
    disparity_px: np.ndarray
    score: np.ndarray
    chance: np.ndarray
    accepted: np.ndarray
    at_edge: np.ndarray
    size_px: int
    reach_px: int
    grid_shape: tuple[int, int]
    rect: Rectification | None
    of_tiles: int = 0
    repeating: np.ndarray | None = None
    ridged: np.ndarray | None = None
    places_px: np.ndarray | None = None
    focal_px: float | None = None
    expected_px: np.ndarray | None = None


def reach_px(rig: Rig, reach_deg: float = REACH_DEG) -> int:
    """``reach_deg`` as rows of this camera (its focal length over its pitch), at least 4."""
    c = rig.camera
    return max(4, math.ceil(math.tan(math.radians(reach_deg)) * c.focal_length_mm / min(c.pixel_pitch_mm)))


def tile_px(shape: tuple[int, int]) -> int:
    """A tile's side (px) on a grid of ``shape`` (H', W'): its shorter side over :data:`TILES_ACROSS`, a
    multiple of 16 within :data:`TILE_PX`."""
    return int(np.clip(16 * round(min(shape) / TILES_ACROSS / 16), *TILE_PX))


def band_pass(image: np.ndarray) -> np.ndarray:
    """The difference of Gaussians (:data:`BAND_SIGMAS_PX`) of an image (H, W), float32."""
    a = np.asarray(image, dtype=np.float32)
    return cv2.GaussianBlur(a, (0, 0), BAND_SIGMAS_PX[0]) - cv2.GaussianBlur(a, (0, 0), BAND_SIGMAS_PX[1])


def _geometry(shape: tuple[int, int], rig: Rig, near_mm: float, far_mm: float):
    """(grid shape (H', W'), disparities (lo, hi) px, rectification or None) of complex images of ``shape``;
    the disparities from :data:`MIN_LAG_PX` at least."""
    rect = rectification(rig, near_mm, far_mm)
    if rect is None:
        grid, (lo, hi) = shape, disparity_range(rig, near_mm, far_mm, width_px=shape[1])
    else:
        grid = (rect.size_px[1], rect.size_px[0])
        lo, hi = disparity_range(rig, near_mm, far_mm, rect, width_px=grid[1])
    return grid, (max(lo, MIN_LAG_PX), max(hi, MIN_LAG_PX + 1.0)), rect


def _null_rows(y: int, rows: list[int], size: int) -> list[int]:
    """The first rows of the :data:`NULLS` bands a tile at row ``y`` is searched in for its chance peak: tile
    rows at least two tiles away, spread over the grid."""
    far = [yy for yy in rows if abs(yy - y) >= 2 * size]
    return far[:: max(1, len(far) // NULLS)][:NULLS]


def _band_passed(image, rig: Rig, rect, bands: list[tuple[int, int]], shape: tuple[int, int]):
    """The left and right grids (H', W') of a complex image, band-passed (:func:`band_pass`), made only on
    the grids' rows ``bands`` [(r0, r1), ...] (zero elsewhere; None: every row). Each band is resampled and
    filtered with the filter's reach of rows either side, so its rows are the whole grid's."""
    img = flat_field(np.asarray(image), rig.camera).astype(np.float32)
    if bands is None:
        bands = [(0, shape[0])]
    pad = int(math.ceil(4 * BAND_SIGMAS_PX[1])) + 1       # OpenCV's kernel reaches 4 sigma (float images)
    a, b = np.zeros(shape, np.float32), np.zeros(shape, np.float32)
    for r0, r1 in bands:
        p0, p1 = max(0, r0 - pad), min(shape[0], r1 + pad)
        if rect is None:                             # the paper's geometry: both grids are the image
            a[r0:r1] = b[r0:r1] = band_pass(img[p0:p1])[r0 - p0:r1 - p0]
        else:
            left, right = rectified_images(img, rect, (p0, p1))
            a[r0:r1], b[r0:r1] = band_pass(left)[r0 - p0:r1 - p0], band_pass(right)[r0 - p0:r1 - p0]
    return a, b


def _merged(spans: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Row spans [(r0, r1), ...] merged where they overlap or touch, in order."""
    out: list[list[int]] = []
    for r0, r1 in sorted(spans):
        if out and r0 <= out[-1][1]:
            out[-1][1] = max(out[-1][1], r1)
        else:
            out.append([r0, r1])
    return [(a, b) for a, b in out]


def frame_tiles(image, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0,
                reach_deg: float = REACH_DEG, subset: tuple[int, int] | None = None,
                spread: int | None = None) -> FrameTiles:
    """Every tile's twin row offset in one complex image (H, W) through ``rig``, searched ``reach_deg`` (as
    rows, :func:`reach_px`) either side of its row (module docstring). ``subset`` = (start, count): only
    those of the frame's tiles (row by row, left to right, counted modulo their number ``of_tiles``), as a
    rolling check reads a few per frame; ``spread`` = n: about n of them spread evenly over the field
    (:func:`spread_tiles`), as a quick look at a whole frame; only the rows of the grids the tiles read and
    their chance bands read are resampled then (the same values as the whole grids')."""
    (h, w), (lo, hi), rect = _geometry(np.shape(image)[:2], rig, near_mm, far_mm)
    lo, hi = int(math.floor(lo)), int(math.ceil(hi))
    size, reach = tile_px((h, w)), reach_px(rig, reach_deg)
    step = size // 2                                 # tiles overlap by half: twice the evidence per axis
    rows = list(range(reach, h - size - reach + 1, step))
    cols = list(range(max(lo, 0) + 2, w - size + 1, step))     # near the left edge, the nearer twins only
    at = [(x, y) for y in rows for x in cols]
    places = np.array([(x + 0.5 * (size - 1), y + 0.5 * (size - 1)) for x, y in at], float).reshape(-1, 2)
    bands = None
    if spread is not None and at:
        at = [at[k] for k in spread_tiles(len(rows), len(cols), spread)]
    if (subset is not None or spread is not None) and at:
        if subset is not None:
            at = [at[k % len(at)] for k in range(subset[0], subset[0] + min(subset[1], len(at)))]
        read = {yy for _, y in at for yy in _null_rows(y, rows, size)}
        own = size if rect is not None else reach      # a build's tiles read their own grid a side around
        bands = _merged([(y - reach, y + size + reach) for y in read]
                        + [(max(y - own, 0), min(y + size + own, h)) for _, y in at])
    a, b = _band_passed(image, rig, rect, bands, (h, w))
    read_one = lambda xy: _tile(a, b, xy, (size, reach), (lo, hi), rows)    # noqa: E731
    if len(at) >= THREADED_TILES and pool_size(2) > 1:      # OpenCV's correlations release the GIL
        with ThreadPoolExecutor(pool_size(2)) as pool:
            out = list(pool.map(read_one, at))
    else:
        out = [read_one(xy) for xy in at]
    arr = np.array(out, dtype=float).reshape(-1, 10)
    score, chance, rival, row_rival = arr[:, 4], arr[:, 5], arr[:, 8], arr[:, 9]
    textured = (score >= chance + NULL_MARGIN) & (arr[:, 6] >= MIN_TEXTURE_DN)
    unique = score - rival >= UNIQUE_SHARE * (score - chance)
    ridged = textured & unique & (score - row_rival < UNIQUE_SHARE * (score - chance))
    if rect is not None:          # a build's two grids of one image: the tile's own texture may repeat (_own_repeat)
        for k in np.flatnonzero(textured & unique & ~ridged):
            x, y = at[k]
            unique[k] = _own_repeat(a, a[y:y + size, x:x + size], x, y, lo) < score[k]
    accepted = np.isfinite(arr[:, 2]) & textured & unique & ~ridged
    at_edge = (arr[:, 7] > 0) & textured & unique & ~ridged
    focal = (rig.camera.focal_length_mm / max(rig.camera.pixel_pitch_mm) if rect is None
             else min(rect.camera_matrix[0, 0], rect.camera_matrix[1, 1]))
    expected = None
    if rect is None and rig.mirrors.plate_thickness_mm > 0 and accepted.any():   # the plate's own row shift
        expected = np.zeros(len(accepted))
        expected[accepted] = rig_row_offsets(rig, arr[accepted, :2], arr[accepted, 3])
    return FrameTiles(arr[:, :2], arr[:, 2], arr[:, 3], arr[:, 4], arr[:, 5], accepted, at_edge, size, reach,
                      (h, w), rect, len(rows) * len(cols), textured & ~unique, ridged, places, float(focal),
                      expected)


def spread_tiles(n_rows: int, n_cols: int, count: int) -> list[int]:
    """Indices (row by row) of about ``count`` tiles of an ``n_rows`` x ``n_cols`` grid spread evenly over it:
    every k-th row and every k-th column (k the same both ways, the smallest that keeps no more than
    ``count``; at least 1), each chosen row's columns shifted by half a step from the last's so that the
    field's columns are read in turn. All of them when ``count`` covers the grid."""
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    k = 1
    while math.ceil(n_rows / k) * math.ceil(n_cols / k) > count:
        k += 1
    out = []
    for j, r in enumerate(range(0, n_rows, k)):
        start = (j % 2) * (k // 2)
        out += [r * n_cols + c for c in range(start, n_cols, k)]
    return out


def _tile(a, b, at, size_reach, span, rows) -> tuple:
    """The tile at ``at`` = (x, y) of the left grid ``a`` (``size_reach`` = (side, rows searched either side),
    ``span`` the disparities (lo, hi)) against the right grid ``b``: (u', v', row offset, disparity, score,
    chance, texture DN, 1 if the peak is on the rows' edge, the best match off the peak's lobe on its rows, the
    best on rows off the peak's lobe)."""
    (x, y), (size, reach), (lo, hi) = at, size_reach, span
    t = a[y:y + size, x:x + size]
    texture = float(t.std())
    centre = (x + 0.5 * (size - 1), y + 0.5 * (size - 1))
    x0 = max(x - hi, 0)
    search = b[y - reach:y + size + reach, x0:x + size - lo]
    if search.shape[1] < size + 2 or texture <= 0:
        return (*centre, np.nan, np.nan, -1.0, 1.0, texture, 0, 1.0, 1.0)
    r = cv2.matchTemplate(search, t, cv2.TM_CCOEFF_NORMED)
    i, j = np.unravel_index(int(np.argmax(r)), r.shape)
    # its own rows' search away from its peak: a texture that repeats along the rows matches about as well at
    # another disparity, and which is the twin cannot be told
    lobe = int(BAND_SIGMAS_PX[1])
    away = r[max(0, i - lobe):i + lobe + 1].copy()
    away[:, max(0, j - lobe):j + lobe + 1] = -1.0
    rival = float(away.max())
    # the other rows' best (any disparity): a texture running along one direction matches along a ridge
    rows_best = r.max(axis=1)
    off_rows = np.concatenate([rows_best[:max(0, i - lobe)], rows_best[i + lobe + 1:]])
    row_rival = float(off_rows.max()) if off_rows.size else -1.0
    chance = -1.0
    for yy in _null_rows(y, rows, size):
        chance = max(chance, float(cv2.matchTemplate(b[yy - reach:yy + size + reach, x0:x + size - lo], t,
                                                     cv2.TM_CCOEFF_NORMED).max()))
    edge = int(i == 0 or i == r.shape[0] - 1)
    di, dj = _peak(r, i, j)
    return (*centre, i + di - reach, x - (x0 + j + dj), float(r[i, j]), chance, texture, edge, rival, row_rival)


def _own_repeat(a, t, x: int, y: int, lo: float) -> float:
    """The best correlation (NCC) of the tile ``t`` (side s, at (x, y) of its own grid ``a``) with its own grid
    at shifts within s rows and within s and the smallest disparity ``lo`` columns (less a lobe: no twin's
    echo), off its own lobe. On a build the two grids resample one complex image, and a tile's own pixels
    stand on the right grid where the rectifications disagree, rows off its own: a texture that repeats in
    two directions (a checkerboard) copies that self-image along its lattice into the searched rows and
    disparities, each copy a little weaker, and the search's own rival tests see one copy alone (an
    adversarial trial: a checkerboard through the undrifted misaligned build read "drifted 7.07 +- 0.11 px").
    Its own grid shows the repeat whole: its correlation's peaks (local maxima over a lobe) off its own. A
    tile whose best such peak is as strong as its twin's (its own grid's copy is not degraded by the other
    view's texture and a second resampling, as a twin is) tells no twin: a random texture's peaks there stand
    near its chance level, below any accepted twin's."""
    size, lobe = t.shape[0], int(BAND_SIGMAS_PX[1])
    cols = min(size, int(lo) - lobe)
    y0, y1 = max(y - size, 0), min(y + 2 * size, a.shape[0])
    x0, x1 = max(x - cols, 0), min(x + size + cols, a.shape[1])
    if cols <= lobe or y1 - y0 < size or x1 - x0 < size:
        return -1.0
    r = cv2.matchTemplate(a[y0:y1, x0:x1], t, cv2.TM_CCOEFF_NORMED)
    peaks = r >= cv2.dilate(r, np.ones((2 * lobe + 1, 2 * lobe + 1), np.uint8))   # its own lobe's slope is none
    i, j = y - y0, x - x0                                   # the tile itself
    peaks[max(0, i - lobe):i + lobe + 1, max(0, j - lobe):j + lobe + 1] = False
    return float(r[peaks].max()) if peaks.any() else -1.0


def _peak(r: np.ndarray, i: int, j: int) -> tuple[float, float]:
    """The sub-pixel offset (rows, columns) of the maximum at (i, j) of ``r``: the top of the quadratic
    through its 3 x 3 neighbourhood; NaN when it is on the border or the quadratic has no top within 1 px."""
    if not (0 < i < r.shape[0] - 1 and 0 < j < r.shape[1] - 1):
        return np.nan, np.nan
    z = r[i - 1:i + 2, j - 1:j + 2].astype(float).ravel()
    x, y = np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0])
    x, y = x.ravel(), y.ravel()
    c = np.linalg.lstsq(np.column_stack([np.ones(9), x, y, x * x, x * y, y * y]), z, rcond=None)[0]
    m = np.array([[2 * c[3], c[4]], [c[4], 2 * c[5]]])
    if not (m[0, 0] < 0 and np.linalg.det(m) > 0):
        return np.nan, np.nan
    sx, sy = np.linalg.solve(m, [-c[1], -c[2]])
    if abs(sx) > 1 or abs(sy) > 1:
        return np.nan, np.nan
    return float(sy), float(sx)
