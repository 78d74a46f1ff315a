"""Guided filter (He, Sun & Tang 2013) of every slice of a cost volume, in one Numba kernel.

Per slice p and guide I (box means over a (2r + 1)² window, borders reflected as OpenCV's BORDER_REFLECT):
a = (mean(I·p) − mean(I)·mean(p)) / (var(I) + ε), b = mean(p) − a·mean(I), q = mean(a)·I + mean(b).
The slices run in parallel. A box sum is a sum along the rows by doubling (a few passes over a row that
vectorise) and a running sum down the columns. Each slice streams down its rows with every intermediate
in rings of a few rows that stay in cache (full-slice intermediates made the filter wait on memory);
OpenCV's boxFilter per slice, called from Python, spent most of its time outside the arithmetic.

The kernels are compiled without value-changing fast math (psvs.dense.fastmath), so their float32
arithmetic is IEEE's, and so is every copy LLVM makes of a loop: the vector body, its remainder, and the
scalar copy it runs when a run-time check on the arrays' addresses says the rows written might overlap those
read (a check hoisted out of the loops around it, over bounds wider than the rows used, so it fails whenever
the heap happens to put two work spaces close together). Under fastmath these copies did not agree: the
vector copy divided by an approximate reciprocal (vrcp14ps and a Newton step), the scalar copy exactly, and
the result's last bits depended on where the heap put the work spaces, from one call to the next. The one
division per pixel and slice is a product with the guide's 1 / (var(I) + ε), computed once per call.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from psvs.dense.fastmath import SAFE_MATH


@nb.njit(cache=True, inline="always")
def _reflect(i, n):  # pragma: no cover - compiled
    """OpenCV's BORDER_REFLECT (fedcba|abcdefgh|hgfedcb) for |overhang| <= n."""
    if i < 0:
        return -i - 1
    if i >= n:
        return 2 * n - i - 1
    return i


@nb.njit(cache=True)
def n_levels(r):  # pragma: no cover - compiled
    """Rows of :func:`row_sums`' work space for radius r: ⌊log2(2r + 1)⌋ + 1."""
    n = 1
    while (1 << n) <= 2 * r + 1:
        n += 1
    return n


# psvs.dense.cost's echo kernel compiles this in. Numba's cache only sees a kernel's own file: after an
# edit here, touch cost.py (or clear __pycache__) so that its cached kernel is rebuilt. Its flags (SAFE_MATH)
# change no value: IEEE arithmetic in the echo and in this module's kernels alike. It is a call, not inlined
# by Numba (inline="always"): LLVM inlines it all the same, and Numba's inlining of it (four times into
# :func:`_filter_slices`, a parallel kernel) took 20 s of a first run's compile, for the same speed.
@nb.njit(cache=True, fastmath=SAFE_MATH)
def row_sums(row, out, r, levels, clamp):  # pragma: no cover - compiled
    """out[x] = Σ row[x + j], j = −r..r (row, out: (W,)), beyond the ends the row reflected (OpenCV's
    BORDER_REFLECT) or with ``clamp`` its end values repeated, by doubling: the extended row into
    levels[0]; levels[b] holds the sums of 2^b consecutive entries, each level two shifted reads of the
    one below; the window of 2r + 1 entries is the sum of the levels of its binary digits. A few passes
    that vectorise instead of 2r + 1 (levels: (:func:`n_levels` (r), ≥ W + 2r) work space)."""
    w = row.shape[0]
    n = w + 2 * r
    ext = levels[0]
    mid = ext[r:r + w]
    for i in range(w):
        mid[i] = row[i]
    for j in range(r):                       # reflect: fedcba|abcdef|fedcba; clamp: aaaaaa|abcdef|ffffff
        ext[r - 1 - j] = row[0] if clamp else row[min(j, w - 1)]
        ext[r + w + j] = row[w - 1] if clamp else row[max(w - 1 - j, 0)]
    size = 2 * r + 1
    for b in range(1, levels.shape[0]):
        half = 1 << (b - 1)
        m = n - (1 << b) + 1
        dst, lo, hi = levels[b, :m], levels[b - 1, :m], levels[b - 1, half:half + m]
        for i in range(m):
            dst[i] = lo[i] + hi[i]
    first = True
    off = 0
    for b in range(levels.shape[0] - 1, -1, -1):
        if size & (1 << b):
            src = levels[b, off:off + w]
            if first:
                for i in range(w):
                    out[i] = src[i]
                first = False
            else:
                for i in range(w):
                    out[i] += src[i]
            off += 1 << b


@nb.njit(cache=True)
def _box_mean(src, dst, tmp, r):  # pragma: no cover - compiled
    """dst = mean of src (H, W) over (2r + 1)² windows, reflected borders; tmp (H, W) is work space."""
    h, w = src.shape
    scale = np.float32(1.0 / ((2 * r + 1) * (2 * r + 1)))
    levels = np.empty((n_levels(r), w + 2 * r), np.float32)
    for y in range(h):
        row_sums(src[y], tmp[y], r, levels, False)
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


@nb.njit(cache=True)
def _slide(col, ring, y, h, r, first):  # pragma: no cover - compiled
    """The column sums ``col`` (W,) of the row sums in ``ring`` (2r + 2 rows, row i in slot i mod 2r + 2)
    moved to the window of row y, rows reflect(y − r .. y + r): summed afresh for the first row, else
    the entering row added and the leaving one taken off."""
    n = ring.shape[0]
    w = col.shape[0]
    if first:
        for x in range(w):
            col[x] = 0.0
        for j in range(-r, r + 1):
            src = ring[_reflect(y + j, h) % n]
            for x in range(w):
                col[x] += src[x]
    else:
        add, sub = ring[_reflect(y + r, h) % n], ring[_reflect(y - r - 1, h) % n]
        for x in range(w):
            col[x] += add[x] - sub[x]


@nb.njit(cache=True, parallel=True)
def _filter_slices(volume, guide, weight, r, eps, missing_value, n_chunks, out):  # pragma: no cover - compiled
    """Each slice streams down its rows in three stages r rows apart: row t's p and I·p are summed along
    the row; row t − r gets its means from the running column sums of those, then its a, b and their row
    sums; row t − 2r its output from the running column sums of those. The intermediates live in rings of
    2r + 2 rows, in cache: a slice is read once and written once."""
    n, h, w = volume.shape
    mean_g = np.empty((h, w), np.float32)
    inv_var = np.empty((h, w), np.float32)   # mean(I²), then 1 / (var(I) + ε)
    work = np.empty((h, w), np.float32)
    _box_mean(guide, mean_g, work, r)
    _box_mean(guide * guide, inv_var, work, r)
    one = np.float32(1.0)
    for y in range(h):
        for x in range(w):
            inv_var[y, x] = one / (inv_var[y, x] - mean_g[y, x] * mean_g[y, x] + eps)
    scale = np.float32(1.0 / ((2 * r + 1) * (2 * r + 1)))
    nr = 2 * r + 2
    n_lv = n_levels(r)
    # work space per chunk of slices (one chunk per thread), allocated once, before the parallel loop
    rings = np.empty((n_chunks, 4, nr, w), np.float32)
    rows = np.empty((n_chunks, 6, w), np.float32)
    all_levels = np.empty((n_chunks, n_lv, w + 2 * r), np.float32)
    for c in nb.prange(n_chunks):
        ring_p, ring_gp, ring_a, ring_b = rings[c, 0], rings[c, 1], rings[c, 2], rings[c, 3]  # row sums of p, I·p, a, b
        col_p, col_gp, col_a, col_b = rows[c, 0], rows[c, 1], rows[c, 2], rows[c, 3]          # their column sums
        p, gp = rows[c, 4], rows[c, 5]
        levels = all_levels[c]
        for k in range(c, n, n_chunks):
            for t in range(h + 2 * r):
                if t < h:                          # row t: p (missing counts as 0) and I·p, summed along the row
                    v, g = volume[k, t], guide[t]
                    for x in range(w):
                        val = v[x]
                        val = np.float32(0.0) if val == missing_value else val
                        p[x] = val
                        gp[x] = g[x] * val
                    row_sums(p, ring_p[t % nr], r, levels, False)
                    row_sums(gp, ring_gp[t % nr], r, levels, False)
                y = t - r
                if 0 <= y < h:                     # row t − r: its means, a and b (into p, gp), their row sums
                    _slide(col_p, ring_p, y, h, r, y == 0)
                    _slide(col_gp, ring_gp, y, h, r, y == 0)
                    mg, iv = mean_g[y], inv_var[y]
                    for x in range(w):
                        mp = col_p[x] * scale
                        a = (col_gp[x] * scale - mg[x] * mp) * iv[x]
                        p[x] = a
                        gp[x] = mp - a * mg[x]
                    row_sums(p, ring_a[y % nr], r, levels, False)
                    row_sums(gp, ring_b[y % nr], r, levels, False)
                y = t - 2 * r
                if y >= 0:                         # row t − 2r: q = mean(a)·I + mean(b), weighted
                    _slide(col_a, ring_a, y, h, r, y == 0)
                    _slide(col_b, ring_b, y, h, r, y == 0)
                    g, wt, v = guide[y], weight[y], volume[k, y]
                    for x in range(w):             # into p, which overlaps nothing read: this vectorises
                        q = (col_a[x] * g[x] + col_b[x]) * scale * wt[x]
                        p[x] = missing_value if v[x] == missing_value else q
                    o = out[k, y]                  # (a select stored over its own input compiles to a
                    for x in range(w):             # conditional store: scalar code)
                        o[x] = p[x]
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
    if weight.shape != guide.shape or volume.shape[1:] != guide.shape:
        raise ValueError(f"volume slices {volume.shape[1:]}, guide {guide.shape} and weight {weight.shape} must match")
    return _filter_slices(volume, guide, weight, r, np.float32(eps), np.float32(missing_value), n_chunks, out)
