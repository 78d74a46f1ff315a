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

Disparities below :data:`~psvs.dense.params.MIN_LAG_PX` cannot be told from the image's own smoothness and are
not searched. The default mode first narrows the range to the lags a coarse pass finds (psvs.dense.prune).
A large image or range is searched coarse to fine (psvs.dense.pyramid): the steps above on the image halved
as often as :func:`~psvs.dense.pyramid.pyramid_levels` says, then a band of lags per pixel at each finer level.
Tuning and presets: psvs.dense.params (``params=FAST`` for the fast mode); the map kernels: psvs.dense.maps;
the echo volume: psvs.dense.cost; the volumes kept from call to call: psvs.dense.workspace.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import cv2
import numpy as np

from psvs._budget import check_memory
from psvs.dense.cost import echo_at_winner, fused_cost, one_sided_cost, padded_lags, unit_scaled, weighted_echo
from psvs.dense.maps import consistent, echo_at, fill_from_background, finite_median, upsample
from psvs.dense.params import COARSE, DEFAULT, FAST, MIN_LAG_PX, MIN_SIZE_PX, DenseParams, searched_lags
from psvs.dense.prune import pruned_range, widened, worth_pruning
from psvs.dense.pyramid import (
    REFERENCE_CELLS,
    REFERENCE_PIXELS,
    coarse_level,
    coarse_maps_up,
    pyramid_levels,
    refine_level,
)
from psvs.dense.sgm import Penalties
from psvs.dense.sgm import winners as sgm_winners
from psvs.dense.workspace import Workspace, volume

__all__ = ["DEFAULT", "FAST", "DenseParams", "DenseResult", "Workspace", "check_dense_memory", "check_image",
           "check_range", "dense_disparity", "dense_memory_bytes"]


@dataclass(frozen=True, eq=False)
class DenseResult:
    """Float32 (H, W) maps of the input's size. ``disparity_left[v, u]`` is x_l − x_r (px) of the left-view
    point seen at (u, v); ``disparity_right[v, u]`` the same for the right-view point at (u, v) (so that
    point's left-view twin is at u + d). NaN where no answer. ``confidence_*`` in [0, 1]: the echo
    correlation (filtered and aperture-weighted) of the pixel's own view at its disparity, 0 where the
    value was filled from neighbours. ``searched_px``: the first and last lag searched (px of the input; a lag
    beyond the range asked for at each end, :func:`~psvs.dense.params.searched_lags`), ``asked_px`` the
    disparities the search was asked for (None: not known)."""

    disparity_left: np.ndarray
    disparity_right: np.ndarray
    confidence_left: np.ndarray
    confidence_right: np.ndarray
    searched_px: tuple[float, float]
    asked_px: tuple[float, float] | None = None


def check_image(image, keep_float32: bool = False) -> np.ndarray:
    """The complex image as float64 (H, W) (the array itself when it is one: read, never written), or
    ValueError naming what is wrong. ``keep_float32``: a float32 image stays float32 (a build's rectified
    grids are: their copies to float64 took 4-6 % of a 1440 x 1080 fast-mode map; the kernels work in float32)."""
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
    whole = a.dtype.kind in "biu"           # integers (a camera's grey levels) are finite by construction
    kept = np.float32 if keep_float32 and a.dtype == np.float32 else np.float64
    a = np.ascontiguousarray(a, dtype=kept)   # no copy of an image of that type: nothing here writes into it
    if not whole and not np.all(np.isfinite(a)):
        raise ValueError("complex image has NaN or infinite values")
    return a


def constant_refusal(image) -> str:
    """Why a complex image (H, W) gives no depth map before any work: every pixel the same value (no texture to
    match; a lens cap, a blank upload); "" otherwise. ``psvs disparity`` and the page's dense run refuse it alike."""
    a = np.asarray(image)
    if a.size and a.min() == a.max():
        return f"the complex image is constant (every pixel {a.flat[0]:g}): no texture to match"
    return ""


def check_range(d_min: float, d_max: float, width: int) -> None:
    """ValueError unless 0 ≤ d_min < d_max < width (px) and d_max is at least :data:`MIN_LAG_PX`. A range between
    two whole px is searched on the lags either side (:func:`~psvs.dense.params.searched_lags`)."""
    if not (math.isfinite(d_min) and math.isfinite(d_max)) or d_min < 0:
        raise ValueError(f"disparity range must be finite and >= 0, got {d_min}..{d_max}")
    if d_max <= d_min:
        raise ValueError(f"disparity range is empty: min {d_min} >= max {d_max}")
    if d_max >= width:
        raise ValueError(f"disparity range up to {d_max} px is wider than the image ({width} px)")
    if d_max < MIN_LAG_PX:
        raise ValueError(f"disparities below {MIN_LAG_PX} px cannot be measured in a complex image "
                         f"(range {d_min}..{d_max})")


def _check_params(params) -> DenseParams:
    """``params`` itself, or TypeError when it is not a :class:`DenseParams` (e.g. None: pass DEFAULT)."""
    if not isinstance(params, DenseParams):
        raise TypeError(f"params must be a DenseParams (DEFAULT, FAST or your own), got {params!r}")
    return params


#: Peak bytes per cell (pixel x searched disparity, the lags padded to whole vectors) of the cost volumes
#: at the working scale: three float32 volumes (the echo, the costs: the fused cost, then each view's of the
#: second pass in turn, and SGM's sums); and per pixel of the full image. (Measured on 640x480, 62 lags, neither
#: pruned nor a pyramid, with five volumes: the peak resident memory grew 485 MiB, the estimate 492 MiB.)
CELL_BYTES = 12
PIXEL_BYTES = 400
#: Bytes per pixel and band lag of a pyramid's finer level: both maps' band costs and sums, float32.
BAND_BYTES = 16


def dense_memory_bytes(h: int, w: int, d_min: float, d_max: float, params: DenseParams = DEFAULT) -> int:
    """Estimated peak memory (bytes) of :func:`dense_disparity` with ``params`` on an (h, w) image searching
    d_min..d_max px (with a pyramid: its coarse level's search, and the band volumes of the finest level)."""
    p = _check_params(params)
    levels = pyramid_levels(h, w, d_min, d_max) if p.pyramid else 0
    if levels:
        k = 2 ** beyond_working_level(levels, p) * p.scale
        coarse = dense_memory_bytes(max(1, h // k), max(1, w // k), d_min / k, d_max / k, top_params(p))
        need = coarse + BAND_BYTES * p.band_lags * (h // p.scale) * (w // p.scale) + PIXEL_BYTES * h * w
        if may_prune_to_one_level(h, w, p):     # or one level over the widest range that needs no pyramid
            lo = max(d_min, MIN_LAG_PX)
            widest = lo + REFERENCE_CELLS / (h * w) - 1
            need = max(need, dense_memory_bytes(h, w, lo, min(d_max, widest), replace(p, pyramid=False)))
        return need
    s = p.scale
    first, last = searched_lags(d_min / s, d_max / s, max(1, w // s))
    n_lags = max(1, last - first + 1)
    cells = (h // s) * (w // s) * padded_lags(n_lags)
    if s == 1 and p.prune:   # the coarse pass's volumes, kept beside the full-resolution ones
        cells += (h // COARSE.scale) * (w // COARSE.scale) * padded_lags(max(1, n_lags // COARSE.scale))
    return int(CELL_BYTES * cells + PIXEL_BYTES * h * w)


def check_dense_memory(h: int, w: int, d_min: float, d_max: float, params: DenseParams = DEFAULT,
                       what: str = "disparity range") -> None:
    """ValueError naming ``what`` when the search d_min..d_max px with ``params`` on an (h, w) image does
    not fit in memory."""
    check_memory(dense_memory_bytes(h, w, d_min, d_max, params),
                 f"{what} {d_min:g}..{d_max:g} px on {w}x{h} px", "narrow the range or use --fast")


@dataclass(frozen=True, eq=False)
class ScaleMaps:
    """What one search at the working scale gives: float64 (h, w) maps of the image it searched (the
    input, or its half-resolution copy), disparities in px of that scale (see :class:`DenseResult`), and
    the first and last lag searched (px of that scale)."""

    disparity_left: np.ndarray
    disparity_right: np.ndarray
    confidence_left: np.ndarray
    confidence_right: np.ndarray
    searched_px: tuple[float, float]


def _at_scale(img: np.ndarray, d_min: float, d_max: float, p: DenseParams, img_right: np.ndarray | None = None,
              workspace: Workspace | None = None) -> ScaleMaps:
    """Steps 1-4 of the module docstring on ``img`` (h, w) (and ``img_right``, a build), searching the whole
    px about d_min..d_max (px of ``img``; :func:`~psvs.dense.params.searched_lags`), in ``workspace``'s
    volumes if given."""
    lo, hi = searched_lags(d_min, d_max, img.shape[1])
    lags = np.arange(lo, hi + 1)
    h, w = img.shape
    cost_shape = (h, w, padded_lags(len(lags)))  # the cost volumes' lag axis, padded to whole vectors
    guide = unit_scaled(img)
    echo = weighted_echo(img, lags, p, guide, img_right, out=volume(workspace, "echo", (len(lags), h, w)))
    costs = volume(workspace, "costs", cost_shape)      # the fused cost, then the second pass's views in turn
    fused = fused_cost(echo, lags, costs)
    sgm = volume(workspace, "sgm", cost_shape)          # SGM's sums (work space), one volume for every aggregation
    penalties = Penalties(p.p1, p.p2, p.n_paths, cv2.GaussianBlur(guide, (0, 0), 1.0), p.edge_contrast)
    best, index = sgm_winners(fused, len(lags), penalties, sums=sgm, min_cost=0.0)   # costs >= 0
    d = lags[0] + best                          # (lags: consecutive whole px)
    own, other = echo_at_winner(echo, lags, index)
    keep_l = own >= other - p.ownership_margin
    keep_r = other >= own - p.ownership_margin
    dl, dr = fill_from_background(d, keep_l), fill_from_background(d, keep_r)
    ok_l, ok_r = consistent(dl, dr)
    if p.second_pass:  # each view's own evidence where the other view's texture dominated
        # one view after the other, each on both threads, its cost over the fused one (made again from the echo)
        # and its sums in the one volume (one view a thread took a volume of costs and of sums each: 1.08 GiB
        # for psvs disparity at 640 x 480 over 136 lags against 0.75, the same winners to the bit)
        dl2, dr2 = (lags[0] + sgm_winners(one_sided_cost(echo, lags, keep, view == 1, costs), len(lags), penalties,
                                          sums=sgm, min_cost=0.0)[0] for view, keep in enumerate((keep_l, keep_r)))
        ok2_l, ok2_r = consistent(dl2, dr2)
        dl = fill_from_background(np.where(~ok_l & ok2_l, dl2, dl), ok_l | ok2_l)
        dr = fill_from_background(np.where(~ok_r & ok2_r, dr2, dr), ok_r | ok2_r)
        ok_l, ok_r = ok_l | ok2_l, ok_r | ok2_r
    if p.median_px > 1:
        dl, dr = (finite_median(m, p.median_px) for m in (dl, dr))
    conf_l = np.where(ok_l, np.clip(echo_at(echo, lags, dl, False), 0, 1), 0.0)
    conf_r = np.where(ok_r, np.clip(echo_at(echo, lags, dr, True), 0, 1), 0.0)
    return ScaleMaps(dl, dr, conf_l, conf_r, (float(lags[0]), float(lags[-1])))


def _pruned_search(img: np.ndarray, d_min: float, d_max: float, right: np.ndarray | None,
                   workspace: Workspace | None) -> tuple[float, float]:
    """The range (px) to search at full resolution: :func:`~psvs.dense.prune.pruned_range` of a coarse
    pass (:data:`~psvs.dense.params.COARSE`) over d_min..d_max, :func:`~psvs.dense.prune.widened`; d_min..d_max
    itself when :func:`~psvs.dense.prune.worth_pruning` says it is too narrow to prune."""
    if not worth_pruning(d_min, d_max):
        return d_min, d_max
    with warnings.catch_warnings():   # a coarse image may be constant where the full one is not: no warning
        warnings.simplefilter("ignore", RuntimeWarning)
        coarse = dense_disparity(img, d_min, d_max, params=COARSE, image_right=right,
                                 workspace=None if workspace is None else workspace.coarse)
    lo, hi = pruned_range(coarse, d_min, d_max, img.shape[0] * img.shape[1])
    return widened(lo, hi, d_min, d_max)


def may_prune_to_one_level(h: int, w: int, p: DenseParams) -> bool:
    """Whether a pyramid that an (h, w) image's range asks for (:func:`~psvs.dense.pyramid.pyramid_levels`)
    may give way to one level over the range a coarse pass finds in the scene: the default mode (full
    resolution, pruned) on an image small enough for one level whatever its range. Its coarse level, at half
    resolution, fills the borders of near objects with the background behind them (its windows span twice the
    scene), and the bands about that answer cannot reach back: on the default rig's `textured` scene asked
    for 350-1200 mm (86..286 px, a pyramid), 10.4 % of the pixels more than 2 % off and 30 % of the near
    objects; over the 88..217 px the scene holds, one level, 6.2 % and 8.3 %, as asked for 400-1200 mm. A
    wider range asked for than the scene shows must not give a worse map."""
    return p.scale == 1 and p.prune and h * w <= 2 * REFERENCE_PIXELS


def _full_resolution(img: np.ndarray, d_min: float, d_max: float, p: DenseParams, right: np.ndarray | None,
                     workspace: Workspace | None) -> DenseResult:
    """:func:`dense_disparity` at full resolution (``p.scale`` 1), the range pruned first if ``p.prune``."""
    if p.prune:
        d_min, d_max = _pruned_search(img, float(d_min), float(d_max), right, workspace)
    m = _at_scale(img, d_min, d_max, p, right, workspace)
    f32 = lambda a: a.astype(np.float32)  # noqa: E731
    return DenseResult(f32(m.disparity_left), f32(m.disparity_right), f32(m.confidence_left),
                       f32(m.confidence_right), m.searched_px)


def _reduced(img: np.ndarray, d_min: float, d_max: float, p: DenseParams, right: np.ndarray | None,
             workspace: Workspace | None) -> DenseResult:
    """:func:`dense_disparity` on the image reduced ``p.scale`` times (at least :data:`MIN_SIZE_PX` a side),
    the maps brought back to full size and px; at full resolution when the reduced range holds no lag."""
    h, w = img.shape
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
    m = _at_scale(small, dmin_s, dmax_s, p, small_right, workspace)
    return DenseResult(upsample(m.disparity_left, (h, w), fx), upsample(m.disparity_right, (h, w), fx),
                       upsample(m.confidence_left, (h, w)), upsample(m.confidence_right, (h, w)),
                       (m.searched_px[0] * fx, m.searched_px[1] * fx))


def working_level(p: DenseParams) -> int:
    """The pyramid level ``p`` works at: 0 (full resolution) or 1 (half, the fast mode)."""
    return max(0, round(math.log2(p.scale)))


def beyond_working_level(levels: int, p: DenseParams) -> int:
    """How many halvings beyond ``p``'s working level the coarse level lies, for an image whose pyramid
    has ``levels`` (:func:`~psvs.dense.pyramid.pyramid_levels`, counted from full resolution): the coarse
    level is the one the full-resolution search would use, and at least one level beyond the working one,
    so a mode that works at half resolution refines its coarse answer once. (It was ``levels`` beyond the
    working level: the fast mode's coarse level was halved once more than the default mode's, and over
    mv1440's whole 400-1200 mm it was wrong on 14-18 % of the pixels of the façade scenes, against 5-7 %.)
    Where the full-resolution search would use the working level itself (``levels`` <= its halvings), the
    coarse level *is* the working level (0: its whole range searched there by the coarse level's parameters,
    nothing to refine): one level beyond it, a 640 x 480 image's coarse level was 160 x 120 px, and with the
    range widened past the pyramid's threshold (--near-mm 350) the fast mode lost the built-in textured scene's
    near objects whole (adversarial trial, issue 41; 9.5 % of its pixels wrong now, 24.9 % then)."""
    base = working_level(p)
    if base == 0:
        return levels
    return 0 if levels <= base else max(1, levels - base)


def top_params(p: DenseParams) -> DenseParams:
    """The parameters of a pyramid's coarse level: ``p.top`` or ``p``, at scale 1 and without a pyramid."""
    return replace(p if p.top is None else p.top, scale=1, pyramid=False)


def _coarse_to_fine(img: np.ndarray, d_min: float, d_max: float, p: DenseParams, right: np.ndarray | None,
                    workspace: Workspace | None, levels: int) -> DenseResult:
    """:func:`dense_disparity` through an image pyramid (psvs.dense.pyramid): the whole range searched by
    ``p`` (at scale 1) on the coarse level (:func:`beyond_working_level` of the image's ``levels``), then
    each finer level down to the working scale searched in a band about the coarser answer; the maps
    brought back to full size and px."""
    base = working_level(p)
    levels = beyond_working_level(levels, p)
    pyr, pyr_r = coarse_level(img, right, base + levels)
    top = pyr[-1]
    f = img.shape[1] / top.shape[1]
    with warnings.catch_warnings():   # a reduced image may be constant where the full one is not
        warnings.simplefilter("ignore", RuntimeWarning)
        coarse = dense_disparity(top, d_min / f, min(d_max / f, top.shape[1] - 1.0),
                                 params=top_params(p), image_right=pyr_r[-1], workspace=workspace)
    dl, dr = coarse.disparity_left, coarse.disparity_right
    cl, cr = coarse.confidence_left, coarse.confidence_right
    for level in range(base + levels - 1, base - 1, -1):
        im = pyr[level]
        fl = img.shape[1] / im.shape[1]
        up = coarse_maps_up((dl, dr, cl, cr), im.shape)
        dl, dr, cl, cr = refine_level(im, pyr_r[level], up, (d_min / fl, min(d_max / fl, im.shape[1] - 1.0)), p,
                                      workspace, local=level == base and p.finest_local_px > 0)
    if p.refine_median_px > 1:      # (float32: as the maps are returned)
        dl, dr = (finite_median(m, p.refine_median_px, np.float32) for m in (dl, dr))
    h, w = img.shape
    fw = w / dl.shape[1]
    searched = (coarse.searched_px[0] * f, coarse.searched_px[1] * f)
    if dl.shape == img.shape:       # (the maps are this call's own: no copy of those already float32)
        f32 = lambda a: a.astype(np.float32, copy=False)  # noqa: E731
        return DenseResult(f32(dl), f32(dr), f32(cl), f32(cr), searched)
    return DenseResult(upsample(dl, (h, w), fw), upsample(dr, (h, w), fw), upsample(cl, (h, w)),
                       upsample(cr, (h, w)), searched)


def dense_disparity(image, d_min: float, d_max: float, *, params: DenseParams = DEFAULT, image_right=None,
                    workspace: Workspace | None = None) -> DenseResult:
    """Left- and right-view disparity maps (px) of a complex image, searching d_min..d_max px.

    Parameters
    ----------
    image : array_like (H, W)
        The complex image, grey, at least :data:`~psvs.dense.params.MIN_SIZE_PX` px a side.
    d_min, d_max : float
        The disparities to search, px, 0 ≤ d_min < d_max < W; whole px from
        :data:`~psvs.dense.params.MIN_LAG_PX` up, a lag beyond each end (:func:`~psvs.dense.params.searched_lags`).
    params : DenseParams
        The tuning: :data:`~psvs.dense.params.DEFAULT` (full resolution, the range pruned to the scene),
        :data:`~psvs.dense.params.FAST` (half resolution, 4 SGM paths), or your own. A large image or range is
        searched coarse to fine with either (psvs.dense.pyramid; ``DenseParams(pyramid=False)``: one level).
    image_right : array_like (H, W), optional
        On a build (psvs.dense.build): ``image`` is the complex image resampled on the left view's rectified
        grid and this one on the right view's; a left pixel's twin is then sought in it, and the maps are
        in rectified coordinates (the left map on the left grid, the right map on the right grid).
    workspace : Workspace, optional
        Keeps the cost volumes for the next call (a live loop).

    Returns
    -------
    DenseResult
        Float32 (H, W) maps and confidences. A constant image has no echo to measure: the maps are all NaN
        and a RuntimeWarning says so.
    """
    p = _check_params(params)
    img = check_image(image, keep_float32=True)
    right = None
    if image_right is not None:
        right = check_image(image_right, keep_float32=True)
        if right.shape != img.shape:
            raise ValueError(f"the right view's image {right.shape} must match the left view's {img.shape}")
        if right.dtype != img.dtype:        # one type through the kernels
            img, right = img.astype(np.float64), right.astype(np.float64)
    h, w = img.shape
    check_range(float(d_min), float(d_max), w)
    check_dense_memory(h, w, float(d_min), float(d_max), p)
    if np.ptp(img) == 0 and (right is None or np.ptp(right) == 0):
        warnings.warn("complex image is constant: no texture to match, disparity is all NaN", RuntimeWarning,
                      stacklevel=2)
        nan = np.full((h, w), np.nan, np.float32)
        return DenseResult(nan, nan.copy(), np.zeros((h, w), np.float32), np.zeros((h, w), np.float32),
                           (float(d_min), float(d_max)), (float(d_min), float(d_max)))
    return replace(_searched(img, float(d_min), float(d_max), p, right, workspace),
                   asked_px=(float(d_min), float(d_max)))


def _searched(img: np.ndarray, d_min: float, d_max: float, p: DenseParams, right: np.ndarray | None,
              workspace: Workspace | None) -> DenseResult:
    """:func:`dense_disparity`'s maps of a checked, non-constant image: one level, reduced or a pyramid."""
    h, w = img.shape
    levels = pyramid_levels(h, w, d_min, d_max) if p.pyramid else 0
    if levels and may_prune_to_one_level(h, w, p):
        lo, hi = _pruned_search(img, d_min, d_max, right, workspace)
        if pyramid_levels(h, w, lo, hi) == 0:      # the scene's lags fit one level: no pyramid
            return _full_resolution(img, lo, hi, replace(p, prune=False), right, workspace)
    if levels:
        return _coarse_to_fine(img, d_min, d_max, p, right, workspace, levels)
    if p.scale == 1:
        return _full_resolution(img, d_min, d_max, p, right, workspace)
    return _reduced(img, d_min, d_max, p, right, workspace)
