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
but with probability :data:`ALPHA`. The test is made at the
level the method searches the whole range (psvs.dense.pyramid: the image halved as often as
:func:`~psvs.dense.pyramid.pyramid_levels` says, whatever the mode), so its patches see the scene at the scale
they would on a 640 x 480 camera; it costs one multiply-add per pixel, lag and band there, not a second run
of the method.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba as nb
import numpy as np

from psvs.dense.disparity import DenseResult
from psvs.dense.echo_test import ALPHA, EchoTest, echo_test
from psvs.dense.pyramid import coarse_level, pyramid_levels

__all__ = ["ALPHA", "STEP_PX", "TOL_PX", "EchoTrust", "consistent_regions", "echo_trust", "grown", "trusted_maps"]

#: px at the tested level: an answer within this of an echoing lag is supported by it.
TOL_PX = 1.5
#: px: neighbours whose disparities differ by more are not one surface.
STEP_PX = 1.0


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


@nb.njit(cache=True)
def _regions(d, ok, step):  # pragma: no cover - compiled
    h, w = d.shape
    parent = np.arange(h * w)
    for y in range(h):
        for x in range(w):
            if not ok[y, x]:
                continue
            if x + 1 < w and ok[y, x + 1] and abs(d[y, x + 1] - d[y, x]) <= step:
                _union(parent, y * w + x, y * w + x + 1)
            if y + 1 < h and ok[y + 1, x] and abs(d[y + 1, x] - d[y, x]) <= step:
                _union(parent, y * w + x, (y + 1) * w + x)
    root = np.full((h, w), -1, np.int64)
    for y in range(h):
        for x in range(w):
            if ok[y, x]:
                root[y, x] = _find(parent, y * w + x)
    return root


def consistent_regions(disparity: np.ndarray, confidence: np.ndarray) -> tuple[np.ndarray, int]:
    """The consistent regions of a map (module docstring): each pixel's region, int64 (H, W) numbered
    0..R-1 (-1 where the pixel carries no echo of its own), and R."""
    d = np.ascontiguousarray(disparity, dtype=np.float64)
    ok = np.ascontiguousarray((np.asarray(confidence) > 0) & np.isfinite(d))
    root = _regions(d, ok, STEP_PX)
    labels = np.full(root.shape, -1, np.int64)
    found, labels[ok] = np.unique(root[ok], return_inverse=True)
    return labels, len(found)


def grown(anchored: np.ndarray, disparity: np.ndarray, confidence: np.ndarray) -> np.ndarray:
    """``anchored`` (H, W bool) and every consistent region of the map that holds an anchored pixel (the
    regions as :func:`consistent_regions` finds them, named by their root pixel: no renumbering needed)."""
    d = np.ascontiguousarray(disparity, dtype=np.float64)
    ok = np.ascontiguousarray((np.asarray(confidence) > 0) & np.isfinite(d))
    root = _regions(d, ok, STEP_PX)
    hit = np.zeros(root.size + 1, bool)          # the last entry: "no region" (root -1), never hit
    hit[root[ok & anchored]] = True
    hit[-1] = False
    return anchored | hit[root]


@dataclass(frozen=True, eq=False)
class EchoTrust:
    """``trusted_left``/``trusted_right`` (H, W) bool: the pixels whose answer the echo supports beyond chance
    (module docstring); ``test`` the echo test behind it (:class:`~psvs.dense.echo_test.EchoTest`, at the
    tested level) and ``level`` how many times the image was halved for it."""

    trusted_left: np.ndarray
    trusted_right: np.ndarray
    test: EchoTest
    level: int

    @property
    def count(self) -> int:
        """Trusted pixels of the left map."""
        return int(self.trusted_left.sum())


def _supported(test: EchoTest, disparity: np.ndarray, confidence: np.ndarray, scale: float, right: bool) -> np.ndarray:
    """Which pixels of one map (H, W) are trusted: anchored (they carry their own echo and lie in a patch
    echoing at their disparity), or in a consistent region with an anchored pixel and not where the texture
    repeats along the rows (the echo test's ambiguous cells)."""
    v, u = np.nonzero((confidence > 0) & np.isfinite(disparity))
    d = disparity[v, u].astype(np.float64) / scale
    at = u / scale + (d if right else 0.0)
    anchored = np.zeros(disparity.shape, bool)
    anchored[v, u] = test.covers(d, at, v / scale, TOL_PX)
    if not anchored.any():
        return anchored
    trusted = grown(anchored, disparity, confidence)
    if test.ambiguous.any():    # a region does not grow over a texture that repeats along the rows
        ny, nx = test.ambiguous.shape
        cy = (np.arange(disparity.shape[0]) / scale // test.cell_px).astype(np.int64)
        rows = np.zeros(disparity.shape[0], bool)          # the pixel rows of cell rows holding such cells
        rows[cy < ny] = test.ambiguous.any(axis=1)[cy[cy < ny]]
        k = np.flatnonzero(rows[v])
        cx = (at[k] // test.cell_px).astype(np.int64)
        k, cx = k[(cx >= 0) & (cx < nx)], cx[(cx >= 0) & (cx < nx)]
        trusted[v[k], u[k]] &= ~test.ambiguous[cy[v[k]], cx]
    return trusted


def echo_trust(image, result: DenseResult, image_right=None,
               inside: tuple[np.ndarray, np.ndarray] | None = None) -> EchoTrust:
    """Which pixels of ``result`` (the maps :func:`~psvs.dense.disparity.dense_disparity` gave for ``image``
    (H, W), and ``image_right`` on a build) the echo supports beyond chance (module docstring), whatever the
    parameters the maps were made with. ``inside``: the (left, right) masks (H, W) of the pixels inside each
    view's field (a build's rectified grids)."""
    left = np.asarray(image, dtype=np.float64)
    right = None if image_right is None else np.asarray(image_right, dtype=np.float64)
    lo, hi = result.searched_px
    h, w = left.shape
    level = pyramid_levels(h, w, lo, hi)
    pyr, pyr_r = coarse_level(left, right, level)
    top, top_r = pyr[-1], pyr_r[-1]
    shrink = None
    if inside is not None:
        shrink = tuple(cv2.resize(m.astype(np.uint8), top.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
                       for m in inside)
    scale = w / top.shape[1]
    test = echo_test(top, lo / scale, min(hi / scale, top.shape[1] - 1.0), top_r, shrink)
    return EchoTrust(_supported(test, result.disparity_left, result.confidence_left, scale, False),
                     _supported(test, result.disparity_right, result.confidence_right, scale, True), test, level)


def trusted_maps(result: DenseResult, trust: EchoTrust) -> DenseResult:
    """``result`` with each confidence map 0 where its pixel is not trusted (the disparities unchanged)."""
    zero = np.float32(0)
    return DenseResult(result.disparity_left, result.disparity_right,
                       np.where(trust.trusted_left, result.confidence_left, zero).astype(np.float32),
                       np.where(trust.trusted_right, result.confidence_right, zero).astype(np.float32),
                       result.searched_px)
