"""Coarse to fine: the whole range searched on a reduced image, then each finer level searches only a
narrow band per pixel around what the coarser one found (tSGM-like, Rothermel et al. 2012).

The method's windows (5 x 5 px), smoothing and penalties were chosen on 640 x 480 images: in pixels, so on
an image of 5 times the pixels they see a fifth of the structure, and a search over the whole range costs
pixels x disparities. :func:`pyramid_levels` picks how many times to halve the image, from its size and
the range asked for, so that the coarse level's cost volume is no larger than :data:`REFERENCE_CELLS`
(a 640 x 480 image over the 192 disparities around the default rig's 400-1200 mm) and its size no
larger than :data:`REFERENCE_PIXELS` times 2: the coarse level then sees the scene as the method was
tuned to see it, and a 640 x 480 image over the default rig's range gets no level (the method as it was).

At each finer level (:func:`refine_level`) a pixel's band is B lags (``DenseParams.band_lags``) around the
coarser level's answer, doubled, and its neighbourhood's (a depth edge keeps the pixel's own value); each
view's map is refined from its own evidence (psvs.dense.band), the two maps are checked against each
other, and a pixel that fails keeps the coarser level's answer (without confidence). Both views are
halved together, so a point and its twin stay on the same row, at half the disparity.
"""
from __future__ import annotations

import cv2
import numba as nb
import numpy as np

from psvs.dense.band import band_costs, band_local_winners, band_winners
from psvs.dense.cost import aperture_weight, band_pass, unit_scaled
from psvs.dense.maps import consistent, upsample
from psvs.dense.params import MIN_LAG_PX, DenseParams, searched_lags
from psvs.dense.workspace import Workspace, volume

#: The cost volume (px x px x lags) the method was tuned on: 640 x 480 over 192 disparities.
REFERENCE_CELLS = 640 * 480 * 192
#: px: the image size it was tuned on.
REFERENCE_PIXELS = 640 * 480
#: px: the coarse level keeps at least this many lags above MIN_LAG_PX to search.
MIN_COARSE_LAGS = 16


def pyramid_levels(h: int, w: int, d_min: float, d_max: float) -> int:
    """How many times to halve an (h, w) image searched over d_min..d_max px before the whole range is
    searched (module docstring): the fewest halvings that bring the cost volume within
    :data:`REFERENCE_CELLS` and the image within twice :data:`REFERENCE_PIXELS`, while the coarse level keeps
    :data:`MIN_COARSE_LAGS` lags and 2 x MIN_COARSE_LAGS px a side.

    >>> pyramid_levels(480, 640, 86, 255), pyramid_levels(1130, 1502, 200, 392), pyramid_levels(1080, 1440, 181, 519)
    (0, 1, 2)
    """
    lags = max(1.0, d_max - max(d_min, MIN_LAG_PX) + 1)
    levels = 0
    while (h * w * lags / 8 ** levels > REFERENCE_CELLS or h * w / 4 ** levels > 2 * REFERENCE_PIXELS):
        nxt = levels + 1
        if (d_max / 2 ** nxt < MIN_LAG_PX + MIN_COARSE_LAGS or min(h, w) / 2 ** nxt < 2 * MIN_COARSE_LAGS):
            break
        levels = nxt
    return levels


def halved(img: np.ndarray) -> np.ndarray:
    """``img`` (h, w) reduced to (h // 2, w // 2) by area averaging (both views of a complex image halve
    together: a point and its twin stay on one row, at half the disparity)."""
    return cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2), interpolation=cv2.INTER_AREA)


def coarse_level(img: np.ndarray, right: np.ndarray | None, times: int) -> tuple[list, list]:
    """The pyramid of ``img`` (and ``right``, a build's right grid, or None): the image halved 0..``times``
    times (:func:`halved`), two lists from the finest."""
    pyr, pyr_r = [img], [right]
    for _ in range(times):
        pyr.append(halved(pyr[-1]))
        pyr_r.append(None if right is None else halved(pyr_r[-1]))
    return pyr, pyr_r


def _bands(d: np.ndarray, lo: int, hi: int, n_lanes: int, out: np.ndarray | None = None) -> np.ndarray:
    """Each pixel's first lag (int64 (h, w), into ``out`` if given) of a band of ``n_lanes`` about ``d`` (h, w,
    px; the coarser level's map brought to this level): centred on its 5 x 5 neighbourhood's span when that
    fits in the band with 2 px to spare each side, else on the pixel's own value (a depth edge); within lo..hi."""
    finite = np.isfinite(d)
    if not finite.all():        # (the median only when a pixel needs it: a map is most often finite throughout)
        d = np.where(finite, d, np.median(d[finite]) if finite.any() else lo)
    d = np.ascontiguousarray(d, dtype=np.float32)
    kernel = np.ones((5, 5), np.uint8)
    out = np.empty(d.shape, np.int64) if out is None else out
    _band_starts(d, cv2.erode(d, kernel), cv2.dilate(d, kernel), n_lanes, lo, max(lo, hi - n_lanes + 1), out)
    return out


@nb.njit(cache=True, parallel=True)
def _band_starts(d, d_lo, d_hi, n_lanes, lo, top, out):  # pragma: no cover - compiled
    """:func:`_bands`' centring, rounding and clipping in one pass (float32 as the NumPy expressions were: the
    same starts to the bit)."""
    h, w = d.shape
    half = np.float32((n_lanes - 1) / 2.0)
    spread = np.float32(n_lanes - 4)
    for y in nb.prange(h):
        for x in range(w):
            a, b = d_lo[y, x], d_hi[y, x]
            c = np.float32(0.5) * (a + b) if b - a <= spread else d[y, x]
            out[y, x] = min(max(np.int64(np.rint(c - half)), lo), top)


def window_stats(f: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and inverse deviation of ``f``'s (2r + 1)² windows, float32 (h, w) each."""
    box = lambda a: cv2.boxFilter(a, -1, (2 * r + 1, 2 * r + 1), borderType=cv2.BORDER_REPLICATE)  # noqa: E731
    mu = box(f)
    sq = f * f
    var = box(sq)
    np.maximum(np.subtract(var, np.multiply(mu, mu, out=sq), out=var), 1e-6, out=var)   # (2 temporaries, not 6)
    return mu, np.divide(1.0, np.sqrt(var, out=var), out=var).astype(np.float32, copy=False)


def refine_level(img: np.ndarray, right: np.ndarray | None, coarse: tuple, d_range: tuple[float, float],
                 p: DenseParams, workspace: Workspace | None = None, local: bool = False):
    """One finer level (module docstring): ``img`` (h, w) (``right``: the right view's grid on a build),
    ``coarse`` the two maps of the coarser level and their confidences brought to (h, w) (the maps in this
    level's px), ``d_range`` the disparities asked for (px of this level). Returns (left map, right map,
    left confidence, right confidence), (h, w): the maps float64, the confidences as ``coarse``'s.

    A pixel keeps the coarser level's confidence (ultimately the coarse level's echo at its disparity,
    from the windows tuned to tell an echo from chance) where this level's maps pass the left-right check,
    and has none elsewhere. Both maps come from bands about the same coarser answer, so their agreement
    alone is no test (on an image without echo they agree over whole regions), and a finer level's 3 x 3
    windows correlate about 0.5 by chance."""
    h, w = img.shape
    lo, hi = searched_lags(*d_range, w)
    n = p.band_lags
    r = p.refine_window // 2
    f = band_pass(img, p.sigma_px)
    g = f if right is None else band_pass(right, p.sigma_px)
    mu_f, isd_f = window_stats(f, r)
    mu_g, isd_g = (mu_f, isd_f) if right is None else window_stats(g, r)
    aperture = aperture_weight(f, p.aperture_window, p.aperture_share)
    offsets = np.empty((2, h, w), np.int64)
    for view in range(2):
        _bands(coarse[view], lo, hi, n, offsets[view])
    costs, _ = band_costs(f, g, (mu_f, isd_f, mu_g, isd_g, aperture), offsets, hi, n, r,
                            out=volume(workspace, "band", (2, h, w, n)))
    if local:
        best = band_local_winners(costs, offsets, p.finest_local_px // 2)
    else:
        guide = cv2.GaussianBlur(unit_scaled(img), (0, 0), 1.0)
        best = band_winners(costs, offsets, p.p1, p.p2, p.n_paths, guide, p.edge_contrast,
                            sums=volume(workspace, "band_sums", (2, h, w, n)))
    ok = consistent(best[0], best[1])
    for view in range(2):           # (the winners' own array: no full-size copy)
        np.copyto(best[view], coarse[view], where=~ok[view])
    return best[0], best[1], *(np.where(ok[view], coarse[2 + view], 0.0) for view in range(2))


def coarse_maps_up(maps: tuple, shape: tuple[int, int]) -> tuple:
    """The two maps (h, w, px) of a coarser level and their two confidences brought to ``shape`` (H, W),
    the maps to its px (nearest neighbour: a depth edge stays sharp), float32."""
    factor = shape[1] / maps[0].shape[1]
    return tuple(upsample(m, shape, factor if k < 2 else 1.0) for k, m in enumerate(maps))
