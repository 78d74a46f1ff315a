"""Guided filter (He, Sun & Tang 2013) of every slice of a cost volume, in one Numba kernel.

Per slice p and guide I (box means over a (2r + 1)² window, borders reflected as OpenCV's BORDER_REFLECT):
a = (mean(I·p) − mean(I)·mean(p)) / (var(I) + ε), b = mean(p) − a·mean(I), q = mean(a)·I + mean(b).
The slices run in parallel; each box mean is two separable passes, 2r + 1 shifted adds along the rows and
a running sum down the columns, which vectorise (OpenCV's boxFilter per slice, called from Python, spent
most of its time outside the arithmetic).
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, fastmath=True, inline="always")
def _reflect(i, n):  # pragma: no cover - compiled
    """OpenCV's BORDER_REFLECT (fedcba|abcdefgh|hgfedcb) for |overhang| <= n."""
    if i < 0:
        return -i - 1
    if i >= n:
        return 2 * n - i - 1
    return i


@nb.njit(cache=True, fastmath=True)
def _box_mean(src, dst, tmp, r):  # pragma: no cover - compiled
    """dst = mean of src (H, W) over (2r + 1)² windows, reflected borders; tmp (H, W) is work space."""
    h, w = src.shape
    scale = np.float32(1.0 / ((2 * r + 1) * (2 * r + 1)))
    lo, hi = min(r, w), max(w - r, min(r, w))
    m = hi - lo
    for y in range(h):
        row, out = src[y], tmp[y]
        inner = out[lo:hi]
        first = row[lo - r:hi - r]
        for i in range(m):                   # 0-based loops over slices: no index wrap-around, they vectorise
            inner[i] = first[i]
        for j in range(-r + 1, r + 1):
            seg = row[lo + j:hi + j]
            for i in range(m):
                inner[i] += seg[i]
        for x in range(0, lo):
            s = np.float32(0.0)
            for j in range(-r, r + 1):
                s += row[_reflect(x + j, w)]
            out[x] = s
        for x in range(hi, w):
            s = np.float32(0.0)
            for j in range(-r, r + 1):
                s += row[_reflect(x + j, w)]
            out[x] = s
    col = np.zeros(w, np.float32)          # the vertical window's sum, running down the rows
    for j in range(-r, r + 1):
        row = tmp[_reflect(j, h)]
        for x in range(w):
            col[x] += row[x]
    for y in range(h):
        if y > 0:
            add, sub = tmp[_reflect(y + r, h)], tmp[_reflect(y - r - 1, h)]
            for x in range(w):
                col[x] += add[x] - sub[x]
        out = dst[y]
        for x in range(w):
            out[x] = col[x] * scale


@nb.njit(cache=True, parallel=True, fastmath=True)
def _filter_slices(volume, guide, weight, r, eps, missing_value, n_chunks, out):  # pragma: no cover - compiled
    n, h, w = volume.shape
    mean_g = np.empty((h, w), np.float32)
    var_g = np.empty((h, w), np.float32)
    work = np.empty((h, w), np.float32)
    _box_mean(guide, mean_g, work, r)
    _box_mean(guide * guide, var_g, work, r)
    for y in range(h):
        for x in range(w):
            var_g[y, x] = var_g[y, x] - mean_g[y, x] * mean_g[y, x] + eps
    g1, mg1, vg1, wt1 = guide.reshape(-1), mean_g.reshape(-1), var_g.reshape(-1), weight.reshape(-1)
    for c in nb.prange(n_chunks):         # work space once per chunk of slices
        p = np.empty((h, w), np.float32)
        gp = np.empty((h, w), np.float32)
        mp = np.empty((h, w), np.float32)
        mgp = np.empty((h, w), np.float32)
        tmp = np.empty((h, w), np.float32)
        p1, gp1, mp1, mgp1 = p.reshape(-1), gp.reshape(-1), mp.reshape(-1), mgp.reshape(-1)
        for k in range(c, n, n_chunks):
            v, o = volume[k].reshape(-1), out[k].reshape(-1)     # flat: the loops vectorise
            for i in range(h * w):
                val = v[i]
                val = np.float32(0.0) if val == missing_value else val
                p1[i] = val
                gp1[i] = g1[i] * val
            _box_mean(p, mp, tmp, r)
            _box_mean(gp, mgp, tmp, r)
            for i in range(h * w):               # a into p, b into gp
                a = (mgp1[i] - mg1[i] * mp1[i]) / vg1[i]
                p1[i] = a
                gp1[i] = mp1[i] - a * mg1[i]
            _box_mean(p, mp, tmp, r)
            _box_mean(gp, mgp, tmp, r)
            for i in range(h * w):
                o[i] = missing_value if v[i] == missing_value else (mp1[i] * g1[i] + mgp1[i]) * wt1[i]
    return out


def guided_filter_volume(volume: np.ndarray, guide: np.ndarray, r: int, eps: float, missing_value: float,
                         in_place: bool = False, weight: np.ndarray | None = None) -> np.ndarray:
    """Each slice of ``volume`` (D, H, W) float32 filtered with ``guide`` (H, W) float32, box radius ``r``
    px, regulariser ``eps`` (guide units²), and multiplied by ``weight`` (H, W) float32 when given (in the
    same pass); entries equal to ``missing_value`` count as 0 and keep their value. Float32 (D, H, W):
    ``volume`` itself with ``in_place`` (a slice's input is read before its output is written, pixel by
    pixel), else a new array."""
    n_chunks = max(1, min(len(volume), nb.get_num_threads()))
    out = volume if in_place else np.empty_like(volume)
    if weight is None:
        weight = np.ones(guide.shape, np.float32)
    return _filter_slices(volume, guide, weight, r, np.float32(eps), np.float32(missing_value), n_chunks, out)
