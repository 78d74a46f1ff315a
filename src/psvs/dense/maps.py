"""Operations on disparity maps (H, W) of psvs.dense: filling from the background, the left-right check,
the echo at each pixel's own disparity, the median of the finite values and the return to full size.

The hot loops are Numba kernels, parallel over rows (the cost-volume kernels are in psvs.dense.cost).
"""
from __future__ import annotations

import cv2
import numba as nb
import numpy as np

from psvs.dense.median import median_filter


def fill_from_background(d: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``d`` (H, W, px) where ``keep`` (H, W, bool); elsewhere the smaller of the nearest kept values to the
    left and right on the same row (the farther surface, as for occlusions); NaN on rows with nothing kept.
    Float64 (H, W)."""
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
    """Left-right check of two maps (H, W, px): a left pixel x with disparity d is consistent when the right
    map at x − d holds d (± tol_px), and a right pixel y when the left map at y + d does. (left_ok, right_ok),
    bool (H, W)."""
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


def echo_at(echo: np.ndarray, lags: np.ndarray, d: np.ndarray, right_view: bool) -> np.ndarray:
    """The echo (float64 (H, W)) of ``echo`` (D, H, W; lag k is ``lags[k]`` px, consecutive whole px) at each
    pixel's own disparity ``d`` (H, W, px, rounded to the nearest lag searched), seen from its own view's
    end (the left view's at x, the right view's at x + d); −1 where d is NaN or the right view's end lies
    outside the image."""
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


def finite_median(d: np.ndarray, size: int, dtype=np.float64) -> np.ndarray:
    """Median of each size × size neighbourhood (odd side, px) of the finite values of ``d`` (H, W, px), of
    ``dtype`` (:func:`psvs.dense.median.median_filter`); the non-finite values count as the map's median, and a
    row without any finite value stays NaN."""
    finite = np.isfinite(d)
    if finite.all():
        return median_filter(d, size, dtype)
    if not finite.any():
        return d.astype(dtype)
    out = median_filter(np.where(finite, d, np.median(d[finite])), size, dtype)
    return np.where(np.isnan(d) & ~finite.any(axis=1, keepdims=True), np.nan, out).astype(dtype, copy=False)


def upsample(a: np.ndarray, shape: tuple[int, int], factor: float = 1.0) -> np.ndarray:
    """``a`` (h, w) resized to ``shape`` (H, W) by nearest neighbour and multiplied by ``factor`` (a
    disparity's px at the working scale to full-resolution px), float32."""
    out = cv2.resize(np.asarray(a, dtype=np.float32), (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST)
    if factor != 1.0:
        np.multiply(out, np.float32(factor), out=out)     # in place: no second full-size map
    return out
