"""Dense disparity of both views from one complex image (the paper's closing open problem: "a fast
intelligent algorithm for separation of the pair of images ... to any complex scene").

Method (docs/dense.md):

1. **Echo cost.** C = (1 − s)·L + s·R, so each patch of C recurs d px to its left when it belongs to the left
   view (disparity d = x_l − x_r, eq. 12's denominator) and d px to its right when it belongs to the right
   view. :func:`psvs.dense.cost.echo_correlation` measures the echo on band-passed C with shiftable
   windows; :func:`~psvs.dense.cost.filter_volume` smooths it with C as guide, so it stops at image edges;
   :func:`~psvs.dense.cost.aperture_weight` scales it by how much of the patch varies along x (a patch of
   horizontal stripes echoes at every lag); :func:`~psvs.dense.cost.fused_cost` reads it from both ends of
   each pair.
2. **Layer-agnostic disparity.** Whichever layer dominates a patch, one of the two sees its echo, so the
   cost ``−max(echo, forward)`` (forward: the echo seen from the pair's right-view end, at x + d) followed
   by semi-global aggregation (its jump penalty lowered across C's edges) gives, at every pixel, the
   disparity of the dominant layer there.
3. **Ownership.** A pixel keeps that disparity in the left map when its own left-view echo carries it
   (echo ≥ forward − margin) and in the right map in the opposite case; the rest, where the other view's
   texture dominated, is filled along the row from the farther (smaller-disparity) side, as occlusions are.
4. **Second pass.** Where the two maps then fail the left-right check, each view is matched again from its
   own evidence alone at the pixels it did not own; values that pass the check replace the fill, and what
   is still inconsistent is filled from the farther side. An 11×11 median removes the fills' streaks.

Disparities below :data:`MIN_LAG_PX` cannot be told from the image's own smoothness and are not searched.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import cv2
import numba as nb
import numpy as np

from psvs._memory import check_memory
from psvs.dense.cost import (
    NO_TWIN,
    aperture_weight,
    band_pass,
    echo_at_winner,
    echo_correlation,
    filter_volume,
    fused_cost,
    one_sided_costs,
    padded_lags,
)
from psvs.dense.median import median_filter
from psvs.dense.sgm import winners as sgm_winners

MIN_LAG_PX = 3
MIN_SIZE_PX = 16
MIN_PRUNED_LAGS = 8      # px: ranges of at most twice this are searched whole, and none is pruned below it


@dataclass(frozen=True)
class DenseParams:
    """Tuning of :func:`dense_disparity`; lengths in px of the working scale."""

    sigma_px: float = 0.7          # band-pass: image minus its Gaussian blur of this σ
    window: int = 5                # NCC window side
    shift_window: int = 5          # shiftable-window neighbourhood side (1: plain windows)
    guided_radius: int = 4         # guided filter of the echo volume, box radius (0: none)
    guided_eps: float = 0.01       # its regulariser, in (guide units)², the guide being C scaled to 0..1
    aperture_window: int = 7       # side of the patch whose x-share of gradient energy weights the echo
    aperture_share: float = 0.2    # x-share at which a patch counts as fully informative
    p1: float = 0.3                # SGM penalty of a 1 px disparity step (NCC units)
    p2: float = 16.0               # SGM penalty of a larger jump between like neighbours ...
    edge_contrast: float = 0.06    # ... divided by 1 + |ΔC| / this (C blurred, scaled to 0..1) across edges
    n_paths: int = 8               # SGM paths, 4 or 8
    ownership_margin: float = 0.2  # a pixel's own echo may be this much below the other view's and still own it
    scale: int = 1                 # 2: work at half resolution (the fast mode); lengths are at that scale
    second_pass: bool = True       # re-match, from each view's own evidence, pixels the first pass left inconsistent
    median_px: int = 11            # final median filter of each map (odd side; 1 = none): removes the fill's streaks
    prune: bool = True             # full resolution: search only the lags a coarse pass (FAST) finds in the scene


DEFAULT = DenseParams()
FAST = DenseParams(sigma_px=0.5, window=9, shift_window=1, guided_radius=0, n_paths=4, scale=2, second_pass=False,
                   median_px=1, prune=False)
#: The coarse pass that prunes the default mode's search: the fast mode. (At quarter resolution it would
#: take 12 ms instead of 55 at 160 disparities, but it misses a 64 x 64 px object whose disparity stands
#: apart: tests/dense/test_disparity.py.)
COARSE = FAST


@dataclass(frozen=True, eq=False)
class DenseResult:
    """Float32 (H, W) maps of the input's size. ``disparity_left[v, u]`` is x_l − x_r (px) of the left-view
    point seen at (u, v); ``disparity_right[v, u]`` the same for the right-view point at (u, v) (so that
    point's left-view twin is at u + d). NaN where no answer. ``confidence_*`` in [0, 1]: the echo
    correlation (filtered and aperture-weighted) of the pixel's own view at its disparity, 0 where the
    value was filled from neighbours."""

    disparity_left: np.ndarray
    disparity_right: np.ndarray
    confidence_left: np.ndarray
    confidence_right: np.ndarray
    searched_px: tuple[float, float]


def check_image(image) -> np.ndarray:
    """The complex image as float64 (H, W), or ValueError naming what is wrong."""
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] in (3, 4):
        raise ValueError(f"complex image must be grey (H, W), got colour of shape {a.shape}")
    if a.ndim != 2:
        raise ValueError(f"complex image must be 2-D (H, W), got shape {a.shape}")
    if a.size == 0:
        raise ValueError("complex image is empty")
    if min(a.shape) < MIN_SIZE_PX:
        raise ValueError(f"complex image of {a.shape[1]}x{a.shape[0]} px is too small (at least "
                         f"{MIN_SIZE_PX} px a side)")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError("complex image has NaN or infinite values")
    return a


def check_range(d_min: float, d_max: float, width: int) -> None:
    """ValueError unless 0 ≤ d_min < d_max < width (px)."""
    if not (math.isfinite(d_min) and math.isfinite(d_max)) or d_min < 0:
        raise ValueError(f"disparity range must be finite and >= 0, got {d_min}..{d_max}")
    if d_max <= d_min:
        raise ValueError(f"disparity range is empty: min {d_min} >= max {d_max}")
    if d_max >= width:
        raise ValueError(f"disparity range up to {d_max} px is wider than the image ({width} px)")
    if d_max < MIN_LAG_PX:
        raise ValueError(f"disparities below {MIN_LAG_PX} px cannot be measured in a complex image "
                         f"(range {d_min}..{d_max})")
    if math.floor(d_max) < max(MIN_LAG_PX, math.ceil(d_min)):
        raise ValueError(f"disparity range {d_min}..{d_max} px holds no whole-pixel disparity to search")


#: Peak bytes per cell (pixel x searched disparity, the lags padded to whole vectors) of the cost volumes
#: at the working scale: six float32 volumes (echo, fused cost, SGM's two sums, the second pass's two
#: one-sided costs); and per pixel of the full image. (Measured on 640x480, 62 lags: 485 MiB at the peak,
#: the estimate 553 MiB.)
CELL_BYTES = 24
PIXEL_BYTES = 400


def dense_memory_bytes(h: int, w: int, d_min: float, d_max: float, params: "DenseParams | None" = None) -> int:
    """Estimated peak memory (bytes) of :func:`dense_disparity` on an (h, w) image searching d_min..d_max px."""
    p = params or DEFAULT
    s = p.scale
    n_lags = max(1, math.floor(d_max / s) - max(MIN_LAG_PX, math.ceil(d_min / s)) + 1)
    cells = (h // s) * (w // s) * padded_lags(n_lags)
    if s == 1 and p.prune:   # the coarse pass's volumes, kept beside the full-resolution ones
        cells += (h // COARSE.scale) * (w // COARSE.scale) * padded_lags(max(1, n_lags // COARSE.scale))
    return int(CELL_BYTES * cells + PIXEL_BYTES * h * w)


def check_dense_memory(h: int, w: int, d_min: float, d_max: float, params: "DenseParams | None" = None,
                       what: str = "disparity range") -> None:
    """ValueError naming ``what`` when the search d_min..d_max px on an (h, w) image does not fit in memory."""
    check_memory(dense_memory_bytes(h, w, d_min, d_max, params),
                 f"{what} {d_min:g}..{d_max:g} px on {w}x{h} px", "narrow the range or use --fast")


def fill_from_background(d: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``d`` (H, W) where ``keep``; elsewhere the smaller of the nearest kept values to the left and right
    on the same row (the farther surface, as for occlusions); NaN on rows with nothing kept."""
    return _fill_rows(np.ascontiguousarray(d, dtype=np.float64), np.ascontiguousarray(keep, dtype=np.bool_))


@nb.njit(cache=True, parallel=True)
def _fill_rows(d, keep):  # pragma: no cover - compiled
    h, w = d.shape
    out = np.empty_like(d)
    for y in nb.prange(h):
        last = np.inf
        for x in range(w):  # nearest kept value on the left
            if keep[y, x]:
                last = d[y, x]
            out[y, x] = d[y, x] if keep[y, x] else last
        last = np.inf
        for x in range(w - 1, -1, -1):  # and on the right; keep the smaller
            if keep[y, x]:
                last = d[y, x]
            elif last < out[y, x]:
                out[y, x] = last
            if out[y, x] == np.inf:
                out[y, x] = np.nan
    return out


def consistent(d_left: np.ndarray, d_right: np.ndarray, tol_px: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Left-right check of two maps (H, W): a left pixel x with disparity d is consistent when the right map
    at x − d holds d (± tol_px), and a right pixel y when the left map at y + d does. (left_ok, right_ok)."""
    a = np.ascontiguousarray(d_left, dtype=np.float64)
    b = np.ascontiguousarray(d_right, dtype=np.float64)
    return _consistent(a, b, -1, tol_px), _consistent(b, a, 1, tol_px)


@nb.njit(cache=True, parallel=True)
def _consistent(mine, other, sign, tol):  # pragma: no cover - compiled
    h, w = mine.shape
    ok = np.zeros((h, w), np.bool_)
    for y in nb.prange(h):
        for x in range(w):
            d = mine[y, x]
            if np.isfinite(d):
                xx = x + sign * int(np.rint(d))
                if 0 <= xx < w:
                    ok[y, x] = abs(d - other[y, xx]) <= tol
    return ok


def unit_scaled(img: np.ndarray) -> np.ndarray:
    """``img`` (H, W) mapped linearly so its 1st and 99th percentiles become 0 and 1, float32: the guide
    for the echo filter and the SGM penalties, whatever the image's grey scale."""
    lo, hi = np.percentile(img, (1.0, 99.0))
    if hi <= lo:  # nearly all one value: use the full range (the image is not constant, it was checked)
        lo, hi = float(img.min()), float(img.max())
    return ((img - lo) / max(hi - lo, 1e-12)).astype(np.float32)


def weighted_echo(img: np.ndarray, lags: np.ndarray, p: DenseParams, guide: np.ndarray,
                  img_right: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """The echo volume (D, H, W) of :func:`dense_disparity`: band-passed NCC, guided-filtered with ``guide``
    (the image scaled by :func:`unit_scaled`), weighted by each patch's aperture; :data:`NO_TWIN` where the
    twin lies outside the image (x < d). With ``img_right`` (a build) the twin's patch comes from it. Written
    into ``out`` (D, H, W) when given."""
    features = band_pass(img, p.sigma_px)
    right = None if img_right is None else band_pass(img_right, p.sigma_px)
    echo = echo_correlation(features, lags, p.window, p.shift_window, right, out)
    aperture = aperture_weight(features, p.aperture_window, p.aperture_share)
    if p.guided_radius > 0:         # the filter weighs the slices as it writes them, NO_TWIN kept
        return filter_volume(echo, guide, p.guided_radius, p.guided_eps, in_place=True, weight=aperture)
    echo *= aperture[None]
    for k, d in enumerate(lags):
        echo[k, :, :d] = NO_TWIN
    return echo


class Workspace:
    """The cost volumes of :func:`dense_disparity`, kept from one call to the next (a live loop): fresh
    memory costs page faults on every frame. One per thread (not thread-safe); it holds six volumes
    of (H, W, searched disparities) float32 at the working scale, each as large as the largest asked for
    (a pruned search asks for fewer lags from frame to frame), and those of the coarse pass."""

    def __init__(self):
        self._buffers: dict[str, np.ndarray] = {}
        self._coarse: Workspace | None = None

    def array(self, name: str, shape: tuple) -> np.ndarray:
        """A contiguous float32 array of ``shape`` (contents undefined) in the kept buffer ``name``, which
        grows when too small."""
        size = math.prod(shape)
        buf = self._buffers.get(name)
        if buf is None or buf.size < size:
            buf = self._buffers[name] = np.empty(size, np.float32)
        return buf[:size].reshape(shape)

    @property
    def coarse(self) -> "Workspace":
        """The workspace of the coarse pass that prunes the search (:func:`pruned_range`)."""
        if self._coarse is None:
            self._coarse = Workspace()
        return self._coarse


def _at_scale(img: np.ndarray, d_min: float, d_max: float, p: DenseParams, img_right: np.ndarray | None = None,
              workspace: Workspace | None = None):
    lo = max(MIN_LAG_PX, math.ceil(d_min))
    hi = min(math.floor(d_max), img.shape[1] - 1)
    lags = np.arange(lo, hi + 1)
    h, w = img.shape
    cost_shape = (h, w, padded_lags(len(lags)))  # the cost volumes' lag axis, padded to whole vectors

    def vol(name: str, shape: tuple = cost_shape) -> np.ndarray:
        return workspace.array(name, shape) if workspace is not None else np.empty(shape, np.float32)

    guide = unit_scaled(img)
    echo = weighted_echo(img, lags, p, guide, img_right, out=vol("echo", (len(lags), h, w)))
    fused = fused_cost(echo, lags, vol("fused"))
    sgm = vol("sgm", (2, *cost_shape))          # SGM's sums (work space): one volume, then two
    penalties = dict(p1=p.p1, p2=p.p2, n_paths=p.n_paths, guide=cv2.GaussianBlur(guide, (0, 0), 1.0),
                     tau=p.edge_contrast)
    best, index = sgm_winners(fused, len(lags), **penalties, sums=sgm[0], min_cost=0.0)   # costs >= 0
    d = lags[0] + best                          # (lags: consecutive whole px)
    own, other = echo_at_winner(echo, lags, index)
    keep_l = own >= other - p.ownership_margin
    keep_r = other >= own - p.ownership_margin
    dl, dr = fill_from_background(d, keep_l), fill_from_background(d, keep_r)
    ok_l, ok_r = consistent(dl, dr)
    if p.second_pass:  # each view's own evidence where the other view's texture dominated
        one = one_sided_costs(echo, lags, fused, keep_l, keep_r, vol("one_sided", (2, *cost_shape)))
        best = sgm_winners(one, len(lags), **penalties, sums=sgm, min_cost=0.0)[0]   # one view per thread
        dl2, dr2 = lags[0] + best[0], lags[0] + best[1]
        ok2_l, ok2_r = consistent(dl2, dr2)
        dl = fill_from_background(np.where(~ok_l & ok2_l, dl2, dl), ok_l | ok2_l)
        dr = fill_from_background(np.where(~ok_r & ok2_r, dr2, dr), ok_r | ok2_r)
        ok_l, ok_r = ok_l | ok2_l, ok_r | ok2_r
    if p.median_px > 1:
        dl, dr = (_median(m, p.median_px) for m in (dl, dr))
    conf_l = np.where(ok_l, np.clip(_echo_at(echo, lags, dl, False), 0, 1), 0.0)
    conf_r = np.where(ok_r, np.clip(_echo_at(echo, lags, dr, True), 0, 1), 0.0)
    return dl, dr, conf_l, conf_r, (float(lags[0]), float(lags[-1]))


#: The coarse pass's support for a disparity: at least this share of its pixels (and PRUNE_MIN_PX of them) with
#: a consistent answer within 1 px of it; the pruned range keeps PRUNE_MARGIN_PX (full-resolution px) and
#: PRUNE_MARGIN_SHARE of its span beyond the outermost supported disparities.
PRUNE_MIN_SHARE = 2e-4
PRUNE_MIN_PX = 8
PRUNE_MARGIN_PX = 4.0
PRUNE_MARGIN_SHARE = 0.1


def pruned_range(coarse: DenseResult, d_min: float, d_max: float, n_pixels: int) -> tuple[float, float]:
    """The part of d_min..d_max (px) that the coarse pass ``coarse`` (both maps, full-resolution px) finds
    in the scene: from its smallest to its largest well-supported consistent disparity, widened by a
    margin; the whole range when it finds none. A scene rarely fills a rig's whole working range (a wall
    fills one disparity), and the full-resolution search costs in proportion to the lags searched."""
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


def _prune(img: np.ndarray, d_min: float, d_max: float, right: np.ndarray | None,
           workspace: Workspace | None) -> tuple[float, float]:
    """The range to search at full resolution: :func:`pruned_range` of a coarse pass (:data:`COARSE`),
    widened within d_min..d_max to at least MIN_PRUNED_LAGS px; d_min..d_max itself when that spans no more
    than 2·MIN_PRUNED_LAGS px (the coarse scale then still has lags to search: over 4)."""
    if math.floor(d_max) - max(MIN_LAG_PX, math.ceil(d_min)) <= 2 * MIN_PRUNED_LAGS:
        return d_min, d_max
    h, w = img.shape
    with warnings.catch_warnings():   # a coarse image may be constant where the full one is not: no warning
        warnings.simplefilter("ignore", RuntimeWarning)
        coarse = dense_disparity(img, d_min, d_max, params=COARSE, image_right=right,
                                 workspace=None if workspace is None else workspace.coarse)
    lo, hi = pruned_range(coarse, d_min, d_max, h * w)
    short = MIN_PRUNED_LAGS - (hi - lo)
    if short > 0:                     # one depth near an end of the range: widen, inside the range
        lo, hi = lo - short / 2, hi + short / 2
        lo, hi = (max(d_min, lo - max(0.0, hi - d_max)), min(d_max, hi + max(0.0, d_min - lo)))
    return lo, hi


def _median(d: np.ndarray, size: int) -> np.ndarray:
    """Median of each size × size neighbourhood of the finite values (a row without any stays NaN)."""
    finite = np.isfinite(d)
    if not finite.any():
        return d
    out = median_filter(np.where(finite, d, np.nanmedian(d)), size)
    return np.where(np.isnan(d) & ~finite.any(axis=1, keepdims=True), np.nan, out)


def _echo_at(echo: np.ndarray, lags: np.ndarray, d: np.ndarray, right_view: bool) -> np.ndarray:
    """The echo (H, W) at each pixel's own disparity, seen from its own view's end; −1 where undefined."""
    return _echo_lookup(echo, np.ascontiguousarray(lags, dtype=np.int64), np.ascontiguousarray(d, dtype=np.float64),
                        right_view)


@nb.njit(cache=True, parallel=True)
def _echo_lookup(echo, lags, d, right_view):  # pragma: no cover - compiled
    n, h, w = echo.shape
    out = np.empty((h, w), np.float64)
    for y in nb.prange(h):
        for x in range(w):
            v = d[y, x]
            if not np.isfinite(v):
                out[y, x] = -1.0
                continue
            k = min(max(int(np.rint(v)) - lags[0], 0), n - 1)
            xx = x + lags[k] if right_view else x
            out[y, x] = echo[k, y, xx] if xx < w else -1.0
    return out


def _upsample(a: np.ndarray, shape: tuple[int, int], factor: float = 1.0) -> np.ndarray:
    return cv2.resize(a.astype(np.float32), (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST) * factor


def dense_disparity(image, d_min: float, d_max: float, *, fast: bool = False,
                    params: DenseParams | None = None, image_right=None,
                    workspace: Workspace | None = None) -> DenseResult:
    """Left- and right-view disparity maps (px) of a complex image (H, W), searching d_min..d_max px.

    ``fast`` uses :data:`FAST` (half resolution, 4 SGM paths); ``params`` overrides either. A constant
    image has no echo to measure: the maps are all NaN and a RuntimeWarning says so.

    ``image_right`` (a build, psvs.dense.build): ``image`` is the complex image resampled on the left view's
    rectified grid and this one on the right view's; a left pixel's twin is then sought in it, and the
    maps are in rectified coordinates (the left map on the left grid, the right map on the right grid).

    ``workspace`` (:class:`Workspace`) keeps the cost volumes for the next call (a live loop)."""
    img = check_image(image)
    right = None
    if image_right is not None:
        right = check_image(image_right)
        if right.shape != img.shape:
            raise ValueError(f"the right view's image {right.shape} must match the left view's {img.shape}")
    h, w = img.shape
    check_range(float(d_min), float(d_max), w)
    p = params or (FAST if fast else DEFAULT)
    check_dense_memory(h, w, float(d_min), float(d_max), p)
    if np.ptp(img) == 0 and (right is None or np.ptp(right) == 0):
        warnings.warn("complex image is constant: no texture to match, disparity is all NaN", RuntimeWarning,
                      stacklevel=2)
        nan = np.full((h, w), np.nan, np.float32)
        return DenseResult(nan, nan.copy(), np.zeros((h, w), np.float32), np.zeros((h, w), np.float32),
                           (float(d_min), float(d_max)))
    if p.scale == 1:
        if p.prune:
            d_min, d_max = _prune(img, float(d_min), float(d_max), right, workspace)
        dl, dr, cl, cr, searched = _at_scale(img, d_min, d_max, p, right, workspace)
        f32 = lambda a: a.astype(np.float32)  # noqa: E731
        return DenseResult(f32(dl), f32(dr), f32(cl), f32(cr), searched)
    s = p.scale
    size = (max(MIN_SIZE_PX, w // s), max(MIN_SIZE_PX, h // s))
    small = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    small_right = None if right is None else cv2.resize(right, size, interpolation=cv2.INTER_AREA)
    fx = w / small.shape[1]
    dmin_s = d_min / fx
    dmax_s = min(d_max / fx, small.shape[1] - 1)
    if math.floor(dmax_s) < max(MIN_LAG_PX, math.ceil(dmin_s)):  # too narrow for the coarse scale
        return dense_disparity(img, d_min, d_max, params=replace(p, scale=1), image_right=right,
                               workspace=workspace)
    dl, dr, cl, cr, searched = _at_scale(small, dmin_s, dmax_s, p, small_right, workspace)
    return DenseResult(_upsample(dl, (h, w), fx), _upsample(dr, (h, w), fx), _upsample(cl, (h, w)),
                       _upsample(cr, (h, w)), (searched[0] * fx, searched[1] * fx))
