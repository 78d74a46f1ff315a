"""Echo cost of a complex image: how well the image around x repeats around x − d.

A complex image is C = (1 − s)·L + s·R with R(x − d) = L(x) for a left-view point at x of disparity d
(x_l − x_r, the denominator of the paper's eq. 12). Every textured patch of C therefore appears twice,
d px apart, the left-view copy on the right. The echo at (x, d) is the normalised cross-correlation of C's
band-passed window at x with the window at x − d: high when the left-view content at x has disparity d.
The hot loops are Numba kernels, parallel over lags or rows.
"""
from __future__ import annotations

import cv2
import numba as nb
import numpy as np

from psvs.dense.fastmath import SAFE_MATH
from psvs.dense.guided import guided_filter_volume, n_levels, row_sums
from psvs.dense.params import DenseParams

NO_TWIN = np.float32(-1.0)  # correlation given to lags whose twin window lies outside the image
#: Cost volumes (H, W, D') hold D' = the searched lags rounded up to a multiple of LANES: the extra entries
#: hold PAD_COST, which never wins, so SGM's loops over lags run in whole vectors (no scalar remainder).
LANES = 8
PAD_COST = np.float32(1e6)


def padded_lags(n: int) -> int:
    """The cost volume's lag axis for ``n`` searched lags: n rounded up to a multiple of :data:`LANES`."""
    return -(-n // LANES) * LANES


def band_pass(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """Image minus its Gaussian blur (σ in px), float32 (H, W): keeps the fine texture that identifies a
    patch, drops shading and the smooth part whose self-similarity would mimic an echo at small lags."""
    f = np.asarray(image, dtype=np.float32)
    return f - cv2.GaussianBlur(f, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT)


# Inner loops run over 0-based slices of rows: an index with a variable offset (x + d) would bring Numba's
# negative-index wrap-around into the loop, and then it does not vectorise. (The moves from lag-major to
# (x, lag) order are gathers either way.)

# The shiftable windows' maxima are taken on integer keys of the float32 values: a float max (or select)
# that updates a row in place, a[i] = max(a[i], b[i]), compiles to scalar code here (Numba 0.6x, LLVM),
# the same on int32 vectorises (4x faster; the echo 93 -> 58 ms). order_keys maps a float's bits to an int32
# that orders as the float does (negative floats' magnitude bits flipped); it is its own inverse.
@nb.njit(cache=True, fastmath=SAFE_MATH, inline="always")
def order_keys(a):  # pragma: no cover - compiled
    """Turn the int32 row ``a`` (a float32 row's bits) into order-preserving keys, or back, in place."""
    for i in range(a.shape[0]):
        b = a[i]
        a[i] = b ^ ((b >> 31) & np.int32(0x7FFFFFFF))


@nb.njit(cache=True, fastmath=SAFE_MATH, inline="always")
def _window_max(src, dst, r):  # pragma: no cover - compiled
    """dst[i] = max src[i + j], j = −r..r, over the indices inside the row (int32 rows)."""
    n = src.shape[0]
    for i in range(n):
        dst[i] = src[i]
    for j in range(-r, r + 1):
        lo, hi = max(0, -j), min(n, n - j)
        if hi > lo:
            a, b = dst[lo:hi], src[lo + j:hi + j]
            for i in range(hi - lo):
                v = b[i]
                a[i] = v if v > a[i] else a[i]


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _echo(f, g, mu, isd, mg, isg, lags, r, rs, out):  # noqa: PLR0913  # pragma: no cover - compiled
    """The echo volume (D, H, W) into ``out``. Per lag, the slice streams down its rows in stages: row t's
    products f(x)·g(x − d) summed along the row (rows clamped at the ends); row t − r's window sums from
    the running column sums of those (rows clamped), its NCC from the windows' means and inverse
    deviations, and its maximum along the row over the shiftable neighbourhood; row t − r − rs the
    maximum of those over the neighbourhood's rows. The intermediates live in rings of a few rows."""
    h, w = f.shape
    n = len(lags)
    inv = np.float32(1.0 / ((2 * r + 1) * (2 * r + 1)))
    nr = 2 * r + 2                                 # ring of row sums: the window's rows and the one leaving it
    nm = 2 * rs + 1                                # ring of row maxima
    n_lv = n_levels(r)
    for k in nb.prange(n):
        d = lags[k]
        wd = w - d                                 # columns x = d + i whose twin x − d = i is inside
        o = out[k]
        o[:, :d] = NO_TWIN
        sums = np.empty((nr, wd), np.float32)
        peaks = np.empty((nm, wd), np.int32)       # keys (order_keys) of the row maxima
        prod = np.empty(wd, np.float32)
        col = np.empty(wd, np.float32)
        ncc = np.empty(wd, np.float32)
        ncc_keys = ncc.view(np.int32)
        top = np.empty(wd, np.int32)
        top_values = top.view(np.float32)
        levels = np.empty((n_lv, wd + 2 * r), np.float32)
        for t in range(h + r + rs):
            if t < h:                              # row t: products, summed along the row
                fy, gy = f[t, d:], g[t, :wd]
                for i in range(wd):
                    prod[i] = fy[i] * gy[i]
                row_sums(prod, sums[t % nr], r, levels, True)
            y = t - r
            if 0 <= y < h:                         # row t − r: window sums, NCC, maximum along the row
                if y == 0:
                    for i in range(wd):
                        col[i] = 0.0
                    for j in range(-r, r + 1):
                        src = sums[min(max(j, 0), h - 1) % nr]
                        for i in range(wd):
                            col[i] += src[i]
                else:
                    add, sub = sums[min(y + r, h - 1) % nr], sums[max(y - r - 1, 0) % nr]
                    for i in range(wd):
                        col[i] += add[i] - sub[i]
                dst = ncc if rs > 0 else o[y, d:]
                muy, isdy, mgy, isgy = mu[y, d:], isd[y, d:], mg[y, :wd], isg[y, :wd]
                for i in range(wd):
                    dst[i] = (col[i] * inv - muy[i] * mgy[i]) * (isdy[i] * isgy[i])
                if rs > 0:
                    order_keys(ncc_keys)
                    _window_max(ncc_keys, peaks[y % nm], rs)
            y = t - r - rs
            if rs > 0 and 0 <= y < h:              # row t − r − rs: the maximum over the neighbourhood's rows
                first = peaks[max(0, y - rs) % nm]
                for i in range(wd):
                    top[i] = first[i]
                for j in range(max(0, y - rs) + 1, min(h, y + rs + 1)):
                    src = peaks[j % nm]
                    for i in range(wd):
                        v = src[i]
                        top[i] = v if v > top[i] else top[i]
                order_keys(top)
                dst = o[y, d:]
                for i in range(wd):
                    dst[i] = top_values[i]
    return out


def aperture_weight(features: np.ndarray, window: int, full_share: float) -> np.ndarray:
    """How far each ``window`` × ``window`` patch of ``features`` (H, W) can pin a horizontal echo, float32
    (H, W) in [0, 1]: the share of its gradient energy that lies along x, Σg_x² / (Σg_x² + Σg_y²), over
    ``full_share`` and capped at 1. A lag is a shift along x, so a patch of horizontal stripes repeats at
    every lag and its echo says nothing about d (the aperture problem); worse, its correlation falls off
    slowly with the lag and pulls toward the smallest one. Weighting the echo by this share makes such
    patches neutral, so the aggregation takes their disparity from patches that do carry one."""
    f = np.asarray(features, dtype=np.float32)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, borderType=cv2.BORDER_REFLECT)
    np.multiply(gx, gx, out=gx)         # (in place: each full-size temporary costs its page faults)
    np.multiply(gy, gy, out=gy)
    sx = cv2.boxFilter(gx, -1, (window, window), borderType=cv2.BORDER_REFLECT)
    sy = cv2.boxFilter(gy, -1, (window, window), borderType=cv2.BORDER_REFLECT)
    np.maximum(np.add(sx, sy, out=gx), 1e-12, out=gx)
    np.divide(np.divide(sx, gx, out=sx), full_share, out=sx)   # (a float64 share: computed in float64, as before)
    return np.clip(sx, np.float32(0), np.float32(1), out=sx)


def filter_volume(volume: np.ndarray, guide: np.ndarray, radius: int, eps: float, in_place: bool = False,
                  weight: np.ndarray | None = None) -> np.ndarray:
    """Guided filter (He, Sun & Tang 2013) of each slice of ``volume`` (D, H, W) with ``guide`` (H, W) scaled
    to about 0..1, box radius ``radius`` px and regulariser ``eps`` (guide units²): cost-volume filtering
    (Hosni et al. 2013). Each pixel's cost becomes a local linear function of the guide, so support stops
    at the guide's edges instead of letting a textured surface's echo spread over its neighbour. The
    :data:`NO_TWIN` entries count as 0 (no evidence) and keep their value. ``weight`` (H, W), when given,
    multiplies every filtered slice (in the same pass). ``in_place`` (a contiguous float32 volume) writes
    the result over ``volume``: one volume less to allocate."""
    v = np.ascontiguousarray(volume, dtype=np.float32)
    g = np.asarray(guide)
    if g.shape != v.shape[1:]:
        raise ValueError(f"guide {g.shape} must match the volume's slices {v.shape[1:]}")
    if not 1 <= radius < min(g.shape):
        raise ValueError(f"guided filter radius must be >= 1 px and below the image's {min(g.shape)} px, got {radius}")
    if not eps > 0:
        raise ValueError(f"guided filter eps must be > 0, got {eps}")
    if weight is not None:
        weight = np.ascontiguousarray(weight, dtype=np.float32)
        if weight.shape != g.shape:
            raise ValueError(f"weight {weight.shape} must match the volume's slices {v.shape[1:]}")
    return guided_filter_volume(v, np.ascontiguousarray(guide, dtype=np.float32), int(radius), np.float32(eps), NO_TWIN,
                                in_place and v is volume, weight)


def echo_correlation(features: np.ndarray, lags: np.ndarray, window: int, shift_window: int = 1,
                     features_right: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """NCC of each ``window`` × ``window`` patch (odd side) of ``features`` (H, W) at x with the patch at
    x − d, for each lag d in ``lags`` (px, integers in 1..W−1): float32 (D, H, W) in [−1, 1], :data:`NO_TWIN`
    where x − d is outside the image. With ``shift_window`` > 1 each pixel takes the best of the windows
    that contain it within that size (shiftable windows), so a patch straddling a depth edge can use its
    one-surface side.

    ``features_right`` (H, W), on a build: the patch at x − d is taken from it (the complex image
    resampled on the right view's rectified grid) while the patch at x comes from ``features`` (resampled
    on the left view's): a cross-correlation, which is the echo when both are the same image."""
    if window < 1 or window % 2 == 0:
        raise ValueError(f"window must be an odd number of px, got {window}")
    f = np.ascontiguousarray(features, dtype=np.float32)
    lags = np.ascontiguousarray(lags, dtype=np.int64)
    if lags.size and (lags.min() < 1 or lags.max() >= f.shape[1]):
        raise ValueError(f"lags must lie in 1..{f.shape[1] - 1} px, got {lags.min()}..{lags.max()}")
    box = lambda a: cv2.boxFilter(a, -1, (window, window), borderType=cv2.BORDER_REPLICATE)  # noqa: E731
    stats = lambda a: (box(a), np.sqrt(np.maximum(box(a * a) - box(a) ** 2, 1e-6)).astype(np.float32))  # noqa: E731
    mu, sd = stats(f)
    if features_right is None:
        g, mg, sg = f, mu, sd
    else:
        g = np.ascontiguousarray(features_right, dtype=np.float32)
        if g.shape != f.shape:
            raise ValueError(f"features_right {g.shape} must match features {f.shape}")
        mg, sg = stats(g)
    shape = (len(lags), *f.shape)
    out = _volume(out, shape)
    return _echo(f, g, mu, (1.0 / sd).astype(np.float32), mg, (1.0 / sg).astype(np.float32), lags, window // 2,
                 max(0, shift_window // 2), out)


def _volume(out: np.ndarray | None, shape: tuple) -> np.ndarray:
    """``out`` checked to be a contiguous float32 array of ``shape``, or a new one."""
    if out is None:
        return np.empty(shape, np.float32)
    if out.shape != shape or out.dtype != np.float32 or not out.flags.c_contiguous:
        raise ValueError(f"output volume must be contiguous float32 {shape}, got {out.dtype} {out.shape}")
    return out


def fused_cost(echo: np.ndarray, lags: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Cost (H, W, D') float32 = −max(echo at x, echo seen from the right-view end at x + d), shifted so
    each pixel's minimum is 0: low where *either* view's content at x has its twin at distance d.
    ``echo`` (D, H, W); D' = :func:`padded_lags` (D), the entries past D :data:`PAD_COST`. Written into
    ``out`` when given."""
    n, h, w = echo.shape
    return _fused_cost(echo, np.ascontiguousarray(lags, dtype=np.int64), _volume(out, (h, w, padded_lags(n))))


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _fused_cost(echo, lags, cost):  # pragma: no cover - compiled
    """Per row: the costs in lag-major order, vectorised along x, then moved to (x, lag) order."""
    n, h, w = echo.shape
    for y in nb.prange(h):
        buf = np.empty((n, w), np.float32)
        best = np.full(w, np.float32(1e30), np.float32)
        for k in range(n):
            d = lags[k]
            e, row = echo[k, y], buf[k]
            m = max(w - d, 0)
            ef = e[d:]                                  # the echo seen from the right-view end, x + d
            for x in range(m):
                a, b = e[x], ef[x]
                row[x] = -(a if a > b else b)
            tail = row[m:]
            et = e[m:]
            for x in range(w - m):
                tail[x] = -et[x]
            for x in range(w):
                v = row[x]
                best[x] = v if v < best[x] else best[x]
        out = cost[y]
        for x in range(w):
            bx = best[x]
            for k in range(n):
                out[x, k] = buf[k, x] - bx
            for k in range(n, cost.shape[2]):
                out[x, k] = PAD_COST
    return cost


def echo_at_winner(echo: np.ndarray, lags: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The echo (D, H, W) at each pixel's winning lag (``index`` (H, W), into ``lags``), seen from the
    left-view end (``own``, at x) and from the right-view end (``other``, at x + d; :data:`NO_TWIN` past the
    image): float32 (H, W) each."""
    index = np.ascontiguousarray(index, dtype=np.int32)
    if index.shape != echo.shape[1:]:
        raise ValueError(f"index {index.shape} must match the echo's slices {echo.shape[1:]}")
    if index.size and (index.min() < 0 or index.max() >= echo.shape[0]):
        raise ValueError(f"lag indices must lie in 0..{echo.shape[0] - 1}")
    return _echo_at_winner(echo, np.ascontiguousarray(lags, dtype=np.int64), index)


@nb.njit(cache=True, parallel=True)
def _echo_at_winner(echo, lags, index):  # pragma: no cover - compiled
    n, h, w = echo.shape
    own = np.empty((h, w), np.float32)
    other = np.empty((h, w), np.float32)
    for y in nb.prange(h):
        for x in range(w):
            k = index[y, x]
            own[y, x] = echo[k, y, x]
            xf = x + lags[k]
            other[y, x] = echo[k, y, xf] if xf < w else NO_TWIN
    return own, other


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def one_sided_cost(echo, lags, keep, right, cost):  # pragma: no cover - compiled
    """The cost (H, W, D) of one view's map for the second pass (``right``: the right view's, else the left's):
    the fused cost (:func:`fused_cost`, made again here from ``echo``) where the pixel's own view owns it
    (``keep`` (H, W) bool), else that view's own evidence alone -- the echo at x (left view) or seen from x + d
    (right view) -- shifted to a minimum of 0. Pixels in the band whose twin may lie outside the image (x <
    d_max for the left view, x >= W - d_max for the right) get a neutral, all-zero cost there. Written into
    ``cost`` (H, W, D') float32 (:func:`padded_lags`, the padding :data:`PAD_COST`), which is returned and may
    be the fused cost's own volume: the two views in turn need that one volume, not two beside the fused cost
    (4 of the search's 16 bytes a cell before). Per row, the echo is read once in lag-major order (as stored) into
    two buffers, its negation and the fused cost before its minimum is taken off, then moved to (x, lag) order."""
    n, h, w = echo.shape
    n_pad = cost.shape[2]
    d_max = lags[n - 1]
    for y in nb.prange(h):
        buf = np.empty((n, w), np.float32)       # -echo, lag-major
        fus = np.empty((n, w), np.float32)       # the fused cost less its minimum, lag-major (as _fused_cost)
        low = np.full(w, np.float32(1e30), np.float32)
        for k in range(n):
            d = lags[k]
            e, row, fr = echo[k, y], buf[k], fus[k]
            for x in range(w):
                row[x] = -e[x]
            m = max(w - d, 0)
            ef = e[d:]
            for x in range(m):
                a, b = e[x], ef[x]
                fr[x] = -(a if a > b else b)
            for x in range(m, w):
                fr[x] = -e[x]
            for x in range(w):
                v = fr[x]
                low[x] = v if v < low[x] else low[x]
        for x in range(w):
            out = cost[y, x]
            for k in range(n, n_pad):
                out[k] = PAD_COST
            if keep[y, x]:
                bx = low[x]
                for k in range(n):
                    out[k] = fus[k, x] - bx
            elif (x >= w - d_max) if right else (x < d_max):
                for k in range(n):
                    out[k] = 0.0
            else:                                # (right: x + d < w for every lag, outside the band)
                best = np.float32(1e30)          # finite: the kernel uses fastmath
                for k in range(n):
                    v = buf[k, x + lags[k]] if right else buf[k, x]
                    out[k] = v
                    best = min(best, v)
                for k in range(n):
                    out[k] -= best
    return cost


def unit_scaled(img: np.ndarray) -> np.ndarray:
    """``img`` (H, W) mapped linearly so its 1st and 99th percentiles become 0 and 1, float32: the guide
    for the echo filter and the SGM penalties, whatever the image's grey scale."""
    lo, hi = np.percentile(img, (1.0, 99.0))
    if hi <= lo:  # nearly all one value: use the full range (the image is not constant, it was checked)
        lo, hi = float(img.min()), float(img.max())
    return ((img - lo) / max(hi - lo, 1e-12)).astype(np.float32)


def weighted_echo(img: np.ndarray, lags: np.ndarray, p: DenseParams, guide: np.ndarray,
                  img_right: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """The echo volume (D, H, W) of :func:`psvs.dense.disparity.dense_disparity` for the lags ``lags`` (px):
    band-passed NCC, guided-filtered with ``guide`` (the image scaled by :func:`unit_scaled`), weighted by
    each patch's aperture; :data:`NO_TWIN` where the twin lies outside the image (x < d). With ``img_right``
    (a build) the twin's patch comes from it. Written into ``out`` (D, H, W) when given."""
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
