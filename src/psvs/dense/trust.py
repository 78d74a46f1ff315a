"""Which answers of a dense disparity map the image's echo supports beyond chance.

Every pixel of :func:`psvs.dense.disparity.dense_disparity`'s maps gets a disparity, even on an image with no
echo at all (sensor noise, a blank wall): the aggregation then settles on whatever lag chance favours, and a
5 x 5 window of a noisy image correlates with some window 0.4-0.6 by chance. A pixel's own echo cannot tell
the two apart (a true echo is halved by the other view's texture), and neither can the size of a region of
agreeing answers (the aggregation makes regions of a thousand pixels out of noise). What can is a test whose
chance behaviour is known: :func:`psvs.dense.echo_test.echo_test` asks, for patches of 32 and 64 px and every
lag, whether the patch correlates with its twin patch beyond what chance gives on the same image, at a stated
false alarm for the whole image (:data:`ALPHA`).

A pixel's answer is **anchored** when it carries its own echo (confidence > 0: owned, and passing the
left-right check) and a patch covering it echoes beyond chance within :data:`TOL_PX` of its disparity (a
right-view pixel at x with disparity d: the patch at its left-view twin, x + d). It is **trusted** when it
lies in a consistent region with an anchored pixel: a 4-connected set of pixels that carry their own echo,
neighbours within :data:`STEP_PX` of disparity, one surface (on the built-in textured scene and on Middlebury
Motorcycle the regions add 13 and 56 points of the pixels with a twin to the anchored ones, at the same
share of right answers, docs/dense.md). On an image without echo nothing is anchored, so nothing is trusted
but with probability :data:`ALPHA`. An anchor must also carry texture of its own (its window beyond the
sensor's noise: :mod:`psvs.dense.noise`), and a pixel without is trusted only between textured pixels of its
region along its row or its column: interpolated across a smooth surface, not extrapolated beyond it (the
aggregation gives a plain backdrop beside an object the object's disparity; on Fig. 5b 41 % of the trusted
pixels were such backdrop, 13 % now, the objects' outline). Where patches echo only outside the searched
range nothing is trusted, and where a texture repeats along the rows only a region anchored there
(:mod:`psvs.dense.elsewhere`); on a surface whose echo in the range is a multiple of its texture's period (a
fence, blinds: :func:`psvs.dense.elsewhere.periodic_patches`) nothing, nor in a region reaching it; nor in the
cells of a patch that copies itself along the row more closely than any twin can
(:func:`psvs.dense.echo_test.copied_patches`: stripes, a grating). The test
is made at the level the method searches the whole asked range (psvs.dense.pyramid: the image halved as often as
:func:`~psvs.dense.pyramid.pyramid_levels` says, whatever the mode and whatever range a coarse pass pruned the
search to), so its patches see the scene at the scale
they would on a 640 x 480 camera; it costs one multiply-add per pixel, lag and band there, not a second run
of the method.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numba as nb
import numpy as np

from psvs._threads import pool_size
from psvs.dense.disparity import DenseResult
from psvs.dense.echo_test import ALPHA, EchoTest, echo_test
from psvs.dense.elsewhere import Elsewhere, echo_elsewhere
from psvs.dense.noise import textured_pixels
from psvs.dense.pyramid import coarse_level, pyramid_levels
from psvs.imaging import NoiseLevel, noise_level

__all__ = ["ALPHA", "ASKED_TOL_PX", "STEP_PX", "TOL_PX", "EchoTrust", "bracketed", "consistent_regions",
           "echo_trust", "grown", "trusted_maps"]

#: px at the tested level: an answer within this of an echoing lag is supported by it.
TOL_PX = 1.5
#: px: neighbours whose disparities differ by more are not one surface.
STEP_PX = 1.0
#: px: an answer further than this outside the disparities asked for is not trusted (:func:`within_disparities`).
ASKED_TOL_PX = 0.5


@nb.njit(cache=True)
def _find(parent, i):  # pragma: no cover - compiled
    root = i
    while parent[root] != root:
        root = parent[root]
    while parent[i] != root:
        nxt = parent[i]
        parent[i] = root
        i = nxt
    return root


@nb.njit(cache=True)
def _union(parent, a, b):  # pragma: no cover - compiled
    ra, rb = _find(parent, a), _find(parent, b)
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)


@nb.njit(cache=True, nogil=True)
def _regions(d, ok, step):  # pragma: no cover - compiled
    """Each ``ok`` pixel's region numbered 0..R-1 in the scan order of the regions' first pixels (-1 elsewhere),
    int32 (H, W), and R. One raster pass joining each pixel to its left and upper neighbours (a region's
    root is its first pixel: unions keep the smaller index), then one pass numbering the roots."""
    h, w = d.shape
    parent = np.empty(h * w, np.int32)
    for y in range(h):
        for x in range(w):
            if not ok[y, x]:
                continue
            i = y * w + x
            parent[i] = i
            here = np.float64(d[y, x])      # (float32 maps compared in float64, as converted maps were)
            if x > 0 and ok[y, x - 1] and abs(np.float64(d[y, x - 1]) - here) <= step:
                parent[i] = _find(parent, i - 1)
            if y > 0 and ok[y - 1, x] and abs(np.float64(d[y - 1, x]) - here) <= step:
                _union(parent, i, i - w)
    labels = np.full((h, w), -1, np.int32)
    flat = labels.ravel()
    n = 0
    for i in range(h * w):
        if ok.flat[i]:
            r = _find(parent, i)
            if r == i:
                flat[i] = n
                n += 1
            else:
                flat[i] = flat[r]
    return labels, n


def consistent_regions(disparity: np.ndarray, confidence: np.ndarray) -> tuple[np.ndarray, int]:
    """The consistent regions of a map (module docstring): each pixel's region, int64 (H, W) numbered
    0..R-1 in the scan order of their first pixels (-1 where the pixel carries no echo of its own), and R."""
    labels, n = _labelled(disparity, confidence)
    return labels.astype(np.int64), n


def _labelled(disparity: np.ndarray, confidence: np.ndarray) -> tuple[np.ndarray, int]:
    """(:func:`consistent_regions` as int32, R)."""
    d = _map(disparity)
    ok = np.ascontiguousarray((np.asarray(confidence) > 0) & np.isfinite(d))
    return _regions(d, ok, STEP_PX)


def _map(values: np.ndarray) -> np.ndarray:
    """A map (disparities, confidences) as the kernels read it: C-contiguous float32 or float64 as it is (no
    copy of a float32 map, the dense engine's), any other dtype as float64."""
    d = np.asarray(values)
    return np.ascontiguousarray(d if d.dtype in (np.float32, np.float64) else d.astype(np.float64))


def grown(anchored: np.ndarray, disparity: np.ndarray, confidence: np.ndarray) -> np.ndarray:
    """``anchored`` (H, W bool) and every consistent region of the map that holds an anchored pixel (the
    regions as :func:`consistent_regions` finds them)."""
    return _grow(_map(disparity), _map(confidence), np.ascontiguousarray(anchored, dtype=np.bool_), STEP_PX)[0]


@nb.njit(cache=True, nogil=True)
def _grow(d, confidence, anchored, step):  # pragma: no cover - compiled
    """(:func:`grown`, each pixel's region int32 (H, W) numbered 0..R-1 (-1 none), R): the regions
    (:func:`_regions` of the pixels with confidence and a finite answer), those holding an anchored pixel
    taken whole."""
    h, w = d.shape
    ok = np.empty((h, w), np.bool_)
    for y in range(h):
        for x in range(w):
            ok[y, x] = confidence[y, x] > 0 and np.isfinite(d[y, x])
    labels, n = _regions(d, ok, step)
    hit = np.zeros(n, np.bool_)
    for y in range(h):
        for x in range(w):
            if anchored[y, x] and labels[y, x] >= 0:
                hit[labels[y, x]] = True
    trusted = np.empty((h, w), np.bool_)
    for y in range(h):
        for x in range(w):
            trusted[y, x] = anchored[y, x] or (labels[y, x] >= 0 and hit[labels[y, x]])
    return trusted, labels, n


def bracketed(regions: np.ndarray, textured: np.ndarray) -> np.ndarray:
    """bool (H, W): the pixels with a ``textured`` (H, W bool) pixel of their own region on both sides of them,
    along their row or along their column; ``regions`` (H, W) int, each pixel's region (any id >= 0; -1 none)."""
    regions = np.asarray(regions)
    textured = np.asarray(textured, dtype=bool)
    if regions.ndim != 2 or textured.shape != regions.shape:
        raise ValueError(f"regions {regions.shape} and textured {textured.shape} must be two maps of one shape")
    ids, flat = np.unique(regions, return_inverse=True)
    flat = flat.reshape(regions.shape).astype(np.int32)
    flat[regions < 0] = -1              # numbered 0..R-1 (the kernel's scratch is R long), -1 kept
    return _bracketed(flat, np.ascontiguousarray(textured), len(ids))


@nb.njit(cache=True, nogil=True)
def _between_along_rows(root, textured, first, last, stamp, out):  # pragma: no cover - compiled
    """Set ``out`` where a pixel has a textured pixel of its own region on both sides of it along its row
    (``first``/``last``/``stamp``: scratch, one entry a region)."""
    h, w = root.shape
    stamp[:] = -1
    for y in range(h):
        for x in range(w):
            r = root[y, x]
            if r >= 0 and textured[y, x]:
                if stamp[r] != y:
                    stamp[r], first[r] = y, x
                last[r] = x
        for x in range(w):
            r = root[y, x]
            if r >= 0 and stamp[r] == y and first[r] < x < last[r]:
                out[y, x] = True


@nb.njit(cache=True, nogil=True)
def _bracketed(root, textured, n):  # pragma: no cover - compiled
    """:func:`bracketed` of regions numbered 0..n-1 (-1: none): along the rows, then along the columns (the
    transposed maps)."""
    out = np.zeros(root.shape, np.bool_)
    first, last, stamp = np.zeros(n, np.int32), np.zeros(n, np.int32), np.empty(n, np.int32)
    _between_along_rows(root, textured, first, last, stamp, out)
    _between_along_rows(root.T, textured.T, first, last, stamp, out.T)
    return out


@dataclass(frozen=True, eq=False)
class EchoTrust:
    """``trusted_left``/``trusted_right`` (H, W) bool: the pixels whose answer the echo supports beyond chance
    (module docstring); ``test`` the echo test behind it (:class:`~psvs.dense.echo_test.EchoTest`, at the
    tested level), ``level`` how many times the image was halved for it, ``noise`` the sensor noise level
    (:func:`psvs.dense.noise.noise_level`; of the complex image on a build) a pixel's own texture was judged
    against, and ``elsewhere`` the cells that echo only outside the searched range, where nothing is trusted
    (:class:`~psvs.dense.elsewhere.Elsewhere`, None when not tested)."""

    trusted_left: np.ndarray
    trusted_right: np.ndarray
    test: EchoTest
    level: int
    noise: NoiseLevel | None = None
    elsewhere: Elsewhere | None = None

    @property
    def count(self) -> int:
        """Trusted pixels of the left map."""
        return int(self.trusted_left.sum())


def _anchors(test: EchoTest, disparity: np.ndarray, confidence: np.ndarray, scale: float, right: bool,
             textured: np.ndarray) -> np.ndarray:
    """The anchored pixels of one map (H, W) bool: they carry their own echo and texture, and lie in a patch
    echoing at their disparity."""
    return test.covers_map(disparity, (confidence > 0) & textured, scale, right, TOL_PX)


def _surfaces(anchored: np.ndarray, disparity: np.ndarray, confidence: np.ndarray,
              textured: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, int]:
    """(trusted, each pixel's region, R): the anchored pixels and their consistent regions, a pixel without
    texture of its own only between its region's textured pixels (interpolated across a smooth surface, not
    extrapolated beyond it: a plain backdrop beside an object, given the object's disparity by the aggregation);
    the regions int32 (H, W) numbered 0..R-1 (-1 none; None without an anchor). Serial kernels without the GIL:
    the two maps' run on two threads."""
    if not anchored.any():
        return anchored, None, 0
    return _surface_kernel(_map(disparity), _map(confidence), np.ascontiguousarray(anchored, dtype=np.bool_),
                           np.ascontiguousarray(textured, dtype=np.bool_), STEP_PX)


@nb.njit(cache=True, nogil=True)
def _surface_kernel(d, confidence, anchored, textured, step):  # pragma: no cover - compiled
    """:func:`_surfaces` in one pass a step: the anchored regions grown (:func:`_grow`), then their untextured
    pixels kept where :func:`bracketed` by their region's textured grown pixels."""
    h, w = d.shape
    trusted, labels, n = _grow(d, confidence, anchored, step)
    between = _bracketed(labels, trusted & textured, n)
    for y in range(h):
        for x in range(w):
            trusted[y, x] = trusted[y, x] and (textured[y, x] or between[y, x])
    return trusted, labels, n


def _unambiguous(test: EchoTest, elsewhere: Elsewhere, trusted: np.ndarray, disparity: np.ndarray, scale: float,
                 right: bool) -> np.ndarray:
    """``trusted`` (H, W) without its pixels in the echo test's ambiguous cells (a texture that repeats along the
    rows: a region does not grow over it), in the cells that echo only outside the searched range and in those
    whose echo lies just past one of its ends (:mod:`psvs.dense.elsewhere`: the search stops there, the surface
    does not; the textured scene at 1250-1320 mm searched to 1200 mm was trusted at the end's lag, 1262 mm, on
    8438 px), each pixel placed as :meth:`~psvs.dense.echo_test.EchoTest.covers_map` places it."""
    d = np.ascontiguousarray(disparity)
    if test.ambiguous.any() and trusted.any():
        _clear_ambiguous(trusted, d, test.ambiguous, test.cell_px, float(scale), bool(right))
    for cells in (elsewhere.cells, elsewhere.past_ends.any(axis=0) if elsewhere.past_any else None):
        if cells is not None and cells.any() and trusted.any():
            _clear_ambiguous(trusted, d, cells, elsewhere.cell_px, float(scale * elsewhere.scale), bool(right))
    return trusted


@nb.njit(cache=True, parallel=True)
def _clear_ambiguous(trusted, disparity, ambiguous, cell, scale, right):  # pragma: no cover - compiled
    ny, nx = ambiguous.shape
    for y in nb.prange(trusted.shape[0]):
        cy = int((y / scale) // cell)
        if cy >= ny:
            continue
        for x in range(trusted.shape[1]):
            if trusted[y, x]:
                d = np.float64(disparity[y, x]) / scale
                cx = int((x / scale + (d if right else 0.0)) // cell)
                if 0 <= cx < nx and ambiguous[cy, cx]:
                    trusted[y, x] = False


def _own_repeats(trusted: np.ndarray, anchored: np.ndarray, labels: np.ndarray | None, n: int,
                 elsewhere: Elsewhere, disparity: np.ndarray, scale: float, right: bool) -> np.ndarray:
    """``trusted`` (H, W) without its pixels in the cells of a texture that repeats along the rows
    (:attr:`~psvs.dense.elsewhere.Elsewhere.repeating`) whose region has no ``anchored`` pixel in those cells:
    a surface whose own echo anchors it there keeps its answer; a region grown into it from outside (the
    method answering the texture's repeat, at the lag of the surface beside it) does not. ``labels``: each
    pixel's region numbered 0..n-1 (-1 none)."""
    if labels is None or not elsewhere.repeats or not trusted.any():
        return trusted
    inside = _in_cells(trusted, elsewhere.repeating, elsewhere, disparity, scale, right)
    own = np.zeros(n + 1, bool)             # the last entry: "no region" (label -1), never anchored
    own[labels[anchored & inside & (labels >= 0)]] = True
    return (trusted & ~inside) | (inside & own[labels])


def _in_cells(trusted: np.ndarray, cells: np.ndarray, elsewhere: Elsewhere, disparity: np.ndarray, scale: float,
              right: bool) -> np.ndarray:
    """The pixels of ``trusted`` (H, W) that lie in ``cells`` (ny, nx) of the elsewhere test's grid, each placed as
    :meth:`~psvs.dense.echo_test.EchoTest.covers_map` places it."""
    kept = trusted.copy()
    _clear_ambiguous(kept, np.ascontiguousarray(disparity), cells, elsewhere.cell_px, float(scale * elsewhere.scale),
                     bool(right))
    return trusted & ~kept


def _periodic_surfaces(trusted: np.ndarray, labels: np.ndarray | None, n: int, elsewhere: Elsewhere,
                       disparity: np.ndarray, scale: float, right: bool) -> np.ndarray:
    """``trusted`` (H, W) without the consistent regions (``labels``, numbered 0..n-1, -1 none) that reach into
    the cells whose echo in the range is a repeat (:attr:`~psvs.dense.elsewhere.Elsewhere.periodic`), and so
    without those cells' own pixels (every trusted pixel lies in a region): such a region is the repeating
    surface, answered at a multiple of its period, also where its patches' repeats did not stand out (a tiled
    wall whose rows differ and carry grime: 2 % of the frame was still trusted, all of it at the repeat's lag,
    4 % short of the wall). So too the cells whose echoes in the range mirror a repeat above it
    (:attr:`~psvs.dense.elsewhere.Elsewhere.mirrored`): the surface is answered at its twin's lag or at the
    mirror's, and its patches that cannot see the repeat (near the row's end) lie in the same region."""
    if labels is None or not (elsewhere.periodic_any or elsewhere.mirrored_any) or not trusted.any():
        return trusted
    cells = elsewhere.periodic if not elsewhere.mirrored_any else (
        elsewhere.mirrored if not elsewhere.periodic_any else elsewhere.periodic | elsewhere.mirrored)
    reached = np.zeros(n + 1, bool)         # the last entry: "no region" (label -1)
    reached[labels[_in_cells(trusted, cells, elsewhere, disparity, scale, right)]] = True
    reached[-1] = False
    return trusted & ~reached[labels]


def _supported(test: EchoTest, elsewhere: Elsewhere, maps: tuple, scale: float,
               textured: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Which pixels of the (left, right) maps are trusted (module docstring): ``maps`` ((disparity, confidence)
    of each, (H, W)), ``textured`` the two maps' (H, W) bool pixels whose own window carries texture beyond the
    sensor's noise (psvs.dense.noise)."""
    anchors = [_anchors(test, d, c, scale, k == 1, t) for k, ((d, c), t) in enumerate(zip(maps, textured, strict=True))]
    with ThreadPoolExecutor(max_workers=pool_size(2)) as pool:
        grown_maps = list(pool.map(_surfaces, anchors, [d for d, _ in maps], [c for _, c in maps], textured))
    return tuple(_own_repeats(_unambiguous(test, elsewhere, _periodic_surfaces(t, labels, n, elsewhere, d, scale,
                                                                               k == 1), d, scale, k == 1),
                              a, labels, n, elsewhere, d, scale, k == 1)
                 for k, ((t, labels, n), (d, _), a) in enumerate(zip(grown_maps, maps, anchors, strict=True)))


def echo_trust(image, result: DenseResult, image_right=None, inside: tuple[np.ndarray, np.ndarray] | None = None,
               textured: tuple[np.ndarray, np.ndarray] | None = None, noise: NoiseLevel | None = None,
               scale_range: tuple[float, float] | None = None,
               answers_px: tuple[float, float] | None = None) -> EchoTrust:
    """Which pixels of ``result`` (the maps :func:`~psvs.dense.disparity.dense_disparity` gave for ``image``
    (H, W), and ``image_right`` on a build) the echo supports beyond chance (module docstring), whatever the
    parameters the maps were made with. ``inside``: the (left, right) masks (H, W) of the pixels inside each
    view's field (a build's rectified grids); ``textured``: the (left, right) masks (H, W) of the pixels whose
    own window carries texture beyond the sensor's noise (:func:`psvs.dense.noise.textured_pixels` of the
    images when None) and ``noise`` the level they were judged against (reported in the result).
    ``scale_range``: the disparities (px) the search was asked to cover (default the maps' ``asked_px``; no
    answer further than :data:`ASKED_TOL_PX` outside them is trusted), which also choose the tested level (the
    maps' ``searched_px`` only when neither is known): the fast mode's coarse pass prunes the search to what a
    scene shows, and a narrower search would test a textured scene at twice the resolution (four times the
    cost) of a blank one. ``answers_px``: the disparities (px) an answer may have to be trusted (within
    :data:`ASKED_TOL_PX`; default the asked ones): a rig's working range traced exactly, without the search's
    margin (:func:`psvs.optics.search_range.working_disparities`)."""
    left = np.asarray(image, dtype=np.float64)
    right = None if image_right is None else np.asarray(image_right, dtype=np.float64)
    lo, hi = result.searched_px
    h, w = left.shape
    asked = scale_range or result.asked_px
    level = pyramid_levels(h, w, *(asked or (lo, hi)))
    pyr, pyr_r = coarse_level(left, right, level)
    top, top_r = pyr[-1], pyr_r[-1]
    shrink = None
    if inside is not None:
        shrink = tuple(cv2.resize(m.astype(np.uint8), top.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
                       for m in inside)
    scale = w / top.shape[1]
    if asked is not None:      # the search's outer lags (a lag past each asked end) support no answer
        lo, hi = max(lo, asked[0]), min(hi, asked[1])
    test = echo_test(top, lo / scale, min(hi / scale, top.shape[1] - 1.0), top_r, shrink)
    away = echo_elsewhere(top, lo / scale, hi / scale, top_r, shrink,
                          asked=None if asked is None else (asked[0] / scale, asked[1] / scale))
    if textured is None:
        noise = noise_level(left)
        tex_left = textured_pixels(left, noise)
        textured = (tex_left, tex_left if right is None else textured_pixels(right, noise_level(right)))
    tex_left, tex_right = (np.asarray(m, dtype=bool) for m in textured)
    if tex_left.shape != left.shape or tex_right.shape != left.shape:
        raise ValueError(f"the texture masks {tex_left.shape}, {tex_right.shape} must have the image's shape "
                         f"{left.shape}")
    maps = ((result.disparity_left, result.confidence_left), (result.disparity_right, result.confidence_right))
    trusted = _supported(test, away, maps, scale, (tex_left, tex_right))
    answers_px = answers_px or asked
    if answers_px is not None:
        trusted = tuple(within_disparities(t, d, answers_px) for t, (d, _) in zip(trusted, maps, strict=True))
    return EchoTrust(*trusted, test, level, noise, away)


def within_disparities(trusted: np.ndarray, disparity: np.ndarray, asked: tuple[float, float]) -> np.ndarray:
    """``trusted`` (H, W) without the answers more than :data:`ASKED_TOL_PX` outside the ``asked`` disparities
    (px): on the lag the search adds beyond each end (psvs.dense.params.searched_lags) a minimum is not
    bracketed, and what lies there is beyond the working range (a planted wall 2.6 px past the far end is
    answered on that outer lag). A live loop holds its supported answers to them frame after frame too."""
    with np.errstate(invalid="ignore"):
        return trusted & (disparity >= asked[0] - ASKED_TOL_PX) & (disparity <= asked[1] + ASKED_TOL_PX)


def trusted_maps(result: DenseResult, trust: EchoTrust) -> DenseResult:
    """``result`` with each confidence map 0 where its pixel is not trusted (the disparities unchanged)."""
    zero = np.float32(0)
    return DenseResult(result.disparity_left, result.disparity_right,
                       np.where(trust.trusted_left, result.confidence_left, zero).astype(np.float32),
                       np.where(trust.trusted_right, result.confidence_right, zero).astype(np.float32),
                       result.searched_px, result.asked_px)
