"""Separate a complex image into its left and right views, given the left view's disparity.

Unknowns: the two views L and R (H, W). Least squares of three terms, solved by conjugate gradients:

* data       C = (1 − s)·L + s·R                    (the complex image, per pixel)
* coupling   R(x − d(x)) = L(x)                      (each left-view point seen again by the right view,
                                                      linear interpolation for sub-pixel d; skipped where
                                                      the right map says the twin is occluded)
* prior      λ·(|∇L|² + |∇R|²)                       (the null space of the mixing is an oscillation of
                                                      period 2d/(2k+1): the smoothness prior picks the
                                                      least-oscillating answer)

Conjugate gradients start from L = R = C and stop after ``iterations`` (30): with *estimated* disparities
the least-squares optimum is not the best answer (wrong ties pull it off), and the early iterates are
better. Measured PSNR of both views against the truth, 10 / 20 / 30 / 50 / 200 iterations: Motorcycle
640x480 21.7 / 21.7 / 21.5 / 21.1 / 20.4 dB, its mirrored pair 22.3 / 22.3 / 22.1 / 21.8 / 21.4 dB, a planted
layered scene 28.4 / 28.6 / 28.5 / 28.4 / 28.4 dB; with its *true* disparities the iterates converge by 30
(29.3 / 29.7 / 29.8 / 29.8 / 29.8 dB). On the ideal rig the normal equations are applied without a matrix
(Numba: data, ties and Laplacian per row, both cores), so 30 iterations on 640x480 take about 0.2 s.

**The prior in scene terms.** λ is given for the paper's camera (1130 px per unit tan(angle)) and scaled to
the grid's own pixels, λ_px = λ·k² with k the grid's px per paper px (:func:`psvs.optics.scale.pixel_scale`:
1 on the 640x480 rigs, 2.05 on mv1440's rectified grid). Why k²: take the same scene sampled k times finer.
A view's gradient per pixel is 1/k of the coarse one and there are k² pixels per coarse pixel, so
Σ|∇|² over the image is unchanged (in two dimensions the Dirichlet energy does not depend on the sampling),
while the data and tie sums, one term per pixel, grow k². The prior's weight against the data, per unit of
solid angle, is therefore λ/k²: a membrane of weight λ against a unit data term smooths over √λ px, which is
√λ/k paper px of angle. λ·Σ|∇|² keeps its angular meaning (the same smoothing length in degrees against
the data) only when λ grows as k². (Two caveats: the mixing's null space, an oscillation of period
2d/(2j+1), costs nothing in the data, so any λ > 0 picks the same least-oscillating answer once converged;
and with independent noise per pixel a fixed λ would be the maximum a posteriori choice, the finer image
holding k² samples per coarse pixel. Measured, the two choices differ by under 0.3 dB.)
Measured on one scene through the clear rig and the 1440x1080 rigs (docs/dense.md, "The prior in scene
terms"): the PSNR is flat in λ over 0.0125-0.2 on the 640x480 rig (±0.2 dB); λ·k² against λ per px moves
the 1440x1080 views by −0.27 to +0.11 dB, and they come out 0.5-3.2 dB closer to the truth than the
640x480 rig's either way.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numba as nb
import numpy as np

from psvs.dense.disparity import check_image
from psvs.dense.fastmath import SAFE_MATH
from psvs.optics.scale import PAPER_FOCAL_PX, pixel_scale


@dataclass(frozen=True)
class SeparationParams:
    """Tuning of :func:`separate_views`: ``smoothness`` λ of the prior in px of the paper's camera (scaled by
    the grid's pixel scale squared, module docstring), ``coupling`` the ties' weight, ``iterations`` of
    conjugate gradients."""

    smoothness: float = 0.05
    coupling: float = 1.0
    iterations: int = 30

    def __post_init__(self):
        if not (np.isfinite(self.smoothness) and self.smoothness > 0):
            raise ValueError(f"smoothness must be a positive number, got {self.smoothness!r}")
        if not (np.isfinite(self.coupling) and self.coupling >= 0):
            raise ValueError(f"coupling must be a number >= 0, got {self.coupling!r}")
        if isinstance(self.iterations, bool) or not isinstance(self.iterations, (int, np.integer)) \
                or self.iterations < 1:
            raise ValueError(f"iterations must be an integer >= 1, got {self.iterations!r}")

    def smoothness_px(self, pixel_scale: float) -> float:
        """λ on a grid of ``pixel_scale`` px per paper px: λ·k² (module docstring).

        Examples
        --------
        >>> SeparationParams().smoothness_px(1.0), round(SeparationParams().smoothness_px(2.0521), 4)
        (0.05, 0.2106)
        """
        if not (np.isfinite(pixel_scale) and pixel_scale > 0):
            raise ValueError(f"pixel_scale must be a positive number, got {pixel_scale!r}")
        return self.smoothness * pixel_scale ** 2


def grid_pixel_scale(rect) -> float:
    """The px per paper px of a build's rectified grid (its focal length K'[0, 0] / 1130)."""
    return float(rect.camera_matrix[0, 0]) / PAPER_FOCAL_PX


#: The chunks of :func:`_dot`: a fixed number, so its order of summation does not depend on the threads.
_DOT_CHUNKS = 64


def sampling_matrix(uv: np.ndarray, h: int, w: int):
    """(N, h*w) bilinear interpolation weights of the grid (h, w) at points uv (N, 2); rows of points off
    the grid are empty."""
    import scipy.sparse as sp  # only view separation on a build: not loaded with psvs.dense
    n = len(uv)
    ok = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
    r = np.flatnonzero(ok)
    u, v = uv[ok, 0], uv[ok, 1]
    u0, v0 = np.minimum(np.floor(u).astype(int), w - 2), np.minimum(np.floor(v).astype(int), h - 2)
    fu, fv = u - u0, v - v0
    rows = np.tile(r, 4)
    cols = np.r_[v0 * w + u0, v0 * w + u0 + 1, (v0 + 1) * w + u0, (v0 + 1) * w + u0 + 1]
    vals = np.r_[(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv]
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, h * w))


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def normal_apply(v, out, h, w, s, coupling, lam, tie_ptr, tie_x, tie_x0, tie_f, mix=True):  # noqa: PLR0913  # pragma: no cover - compiled
    """out = (DᵀD + coupling·TᵀT + lam·GᵀG) v for v = [L; R] (2·h·w,): D mixes each pixel's L and R, T ties
    L(y, x) to R(y, x0 + f) (the ties of row y are tie_ptr[y]:tie_ptr[y + 1]), G the 4-neighbour differences
    of each view (GᵀG: the graph Laplacian, no term across the border). Rows are independent: parallel.
    ``mix`` False leaves DᵀD out (a build's D samples the rectified grids: :func:`_csr_matvec`)."""
    n = h * w
    for y in nb.prange(h):
        for x in range(w):
            for off in (0, n):
                i = off + y * w + x
                c = v[i]
                lap = np.float64(0.0)
                if x > 0:
                    lap += c - v[i - 1]
                if x < w - 1:
                    lap += c - v[i + 1]
                if y > 0:
                    lap += c - v[i - w]
                if y < h - 1:
                    lap += c - v[i + w]
                out[i] = lam * lap
            if mix:
                i = y * w + x
                m = (1.0 - s) * v[i] + s * v[n + i]
                out[i] += (1.0 - s) * m
                out[n + i] += s * m
        for t in range(tie_ptr[y], tie_ptr[y + 1]):
            il, i0 = y * w + tie_x[t], n + y * w + tie_x0[t]
            f = tie_f[t]
            i1 = i0 + 1 if tie_x0[t] < w - 1 else i0
            e = coupling * ((1.0 - f) * v[i0] + f * v[i1] - v[il])
            out[il] -= e
            out[i0] += (1.0 - f) * e
            out[i1] += f * e


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _csr_matvec(indptr, indices, data, x, out, add):  # pragma: no cover - compiled
    """out (+)= A x for A in CSR (indptr, indices, data): rows in parallel."""
    for i in nb.prange(indptr.shape[0] - 1):
        acc = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            acc += data[k] * x[indices[k]]
        out[i] = out[i] + acc if add else acc


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _dot(a, b):  # pragma: no cover - compiled
    """a · b summed in a fixed order (:data:`_DOT_CHUNKS` chunks in parallel, then their sums in turn): the
    same bits on any number of threads (a prange reduction splits the sum by the threads)."""
    n = a.shape[0]
    step = (n + _DOT_CHUNKS - 1) // _DOT_CHUNKS
    part = np.zeros(_DOT_CHUNKS)
    for c in nb.prange(_DOT_CHUNKS):
        acc = 0.0
        for i in range(c * step, min(n, (c + 1) * step)):
            acc += a[i] * b[i]
        part[c] = acc
    total = 0.0
    for c in range(_DOT_CHUNKS):
        total += part[c]
    return total


@nb.njit(cache=True, parallel=True, fastmath=SAFE_MATH)
def _axpy(alpha, x, y):  # pragma: no cover - compiled
    for i in nb.prange(x.shape[0]):
        y[i] += alpha * x[i]


def cg_matrix_free(rhs, start, iterations, rtol, apply):
    """Conjugate gradients (as scipy.sparse.linalg.cg: stop when |r| <= rtol·|b| or after ``iterations``)."""
    x = start.copy()
    r = rhs.copy()
    ax = np.empty_like(x)
    apply(x, ax)
    r -= ax
    stop = (rtol * np.sqrt(_dot(rhs, rhs))) ** 2
    p = r.copy()
    rr = _dot(r, r)
    for _ in range(iterations):
        if rr <= stop:
            break
        apply(p, ax)
        alpha = rr / _dot(p, ax)
        _axpy(alpha, p, x)
        _axpy(-alpha, ax, r)
        rr_new = _dot(r, r)
        p *= rr_new / rr
        p += r
        rr = rr_new
    return x


def separate_views(image, disparity_left, split: float = 0.5, disparity_right=None, *,
                   params: SeparationParams = SeparationParams(), rect=None,
                   pixel_scale: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Left and right views (float64 (H, W), grey levels of the input) of the complex ``image`` (H, W).

    ``disparity_left`` (H, W, px, NaN = unknown) ties each left pixel to its right-view twin;
    ``disparity_right`` (optional, same shape) drops the ties of left pixels whose twin it shows to be a
    different, nearer point (occlusion). ``split`` is s, the right view's share (M1's reflectance).

    ``rect`` (a build, psvs.optics.rectify.Rectification): the maps are on the rectified grids (H', W')
    (psvs.dense.build) and so are the views returned, each on its own view's grid; the data term then
    samples them where each complex-image pixel lies in each view.

    ``pixel_scale``: the grid's px per paper px, by which the prior is scaled (module docstring): give
    :func:`psvs.optics.scale.pixel_scale` of the rig's camera on the paper's geometry; None takes the
    rectified grid's (:func:`grid_pixel_scale`) when ``rect`` is given, else 1 (an image of no known rig)."""
    c = check_image(image)
    dl = np.asarray(disparity_left, dtype=np.float64)
    if not 0.0 < split < 1.0:
        raise ValueError(f"split must lie strictly between 0 and 1, got {split}")
    if rect is None:
        h, w = c.shape
        if dl.shape != c.shape:
            raise ValueError(f"disparity map {dl.shape} does not match the image {c.shape}")
    else:
        w, h = rect.size_px
        if dl.shape != (h, w):
            raise ValueError(f"disparity map {dl.shape} does not match the rectified grid {(h, w)}")
    n = h * w
    k = (1.0 if rect is None else grid_pixel_scale(rect)) if pixel_scale is None else pixel_scale
    smoothness, coupling, iterations = params.smoothness_px(k), params.coupling, params.iterations
    yy, xx, x0, f = coupling_ties(dl, disparity_right, w)
    if rect is None:
        cf = c.ravel()
        rhs = np.r_[(1 - split) * cf, split * cf]
        ptr = np.searchsorted(yy, np.arange(h + 1)).astype(np.int64)
        args = (h, w, float(split), float(coupling), float(smoothness), ptr, xx.astype(np.int64),
                x0.astype(np.int64), f)
        x = cg_matrix_free(rhs, np.r_[cf, cf], iterations, 1e-7, lambda v, out: normal_apply(v, out, *args))
        return x[:n].reshape(h, w), x[n:].reshape(h, w)
    from psvs.dense.build import rectified_images  # (build imports this module's neighbours)
    start = np.concatenate([a.ravel() for a in rectified_images(c, rect)]).astype(np.float64)
    data, data_t = _rect_data(rect, h, w, float(split))
    apply = rect_apply(data, data_t, (yy, xx, x0, f), (h, w), coupling, smoothness)
    rhs = np.empty(2 * n)
    _csr_matvec(data_t.indptr, data_t.indices, data_t.data, c.ravel().astype(np.float64), rhs, False)
    x = cg_matrix_free(rhs, start, iterations, 1e-7, apply)
    return x[:n].reshape(h, w), x[n:].reshape(h, w)


def rect_apply(data, data_t, ties, shape, coupling: float, smoothness: float):
    """(v, out) -> out = (DᵀD + coupling·TᵀT + smoothness·GᵀG) v (2·h·w,), matrix-free and compiled: D
    (N, 2·h·w) and Dᵀ in CSR, the ties (rows, left columns, twin at x0 + f, row-major) and G the
    4-neighbour differences of each view (h, w)."""
    h, w = shape
    yy, xx, x0, f = ties
    ptr = np.searchsorted(yy, np.arange(h + 1)).astype(np.int64)
    args = (h, w, 0.5, float(coupling), float(smoothness), ptr, xx.astype(np.int64), x0.astype(np.int64),
            np.asarray(f, np.float64), False)
    tmp = np.empty(data.shape[0])

    def apply(v, out):
        normal_apply(v, out, *args)
        _csr_matvec(data.indptr, data.indices, data.data, v, tmp, False)
        _csr_matvec(data_t.indptr, data_t.indices, data_t.data, tmp, out, True)

    return apply


#: Each rectification's data operator (its pixel tables are per rig, so is D): rect -> {(h, w, split): (D, Dᵀ)}.
_DATA: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _rect_data(rect, h: int, w: int, split: float):
    """D (H·W, 2·h·w): each complex-image pixel as (1 − s)·L + s·R sampled bilinearly where it lies on
    each view's rectified grid (h, w), and Dᵀ, both CSR; built once per rectification and split."""
    import scipy.sparse as sp
    per_rect = _DATA.setdefault(rect, {})
    key = (h, w, split)
    if key not in per_rect:
        d = sp.hstack([(1 - split) * sampling_matrix(rect.pixel_table("left").reshape(-1, 2), h, w),
                       split * sampling_matrix(rect.pixel_table("right").reshape(-1, 2), h, w)]).tocsr()
        per_rect[key] = (d, d.T.tocsr())
    return per_rect[key]


def coupling_ties(dl: np.ndarray, disparity_right, w: int):
    """The coupling ties of the finite left disparities whose twin is inside the grid and not occluded (the
    right map showing a nearer point there): rows yy, left columns xx, and the twin at x0 + f (0 <= f < 1),
    in row-major order."""
    yy, xx = np.nonzero(np.isfinite(dl))
    xr = xx - dl[yy, xx]
    ok = (xr >= 0) & (xr <= w - 1)
    if disparity_right is not None:
        drm = np.asarray(disparity_right, dtype=np.float64)
        twin = drm[yy, np.clip(np.round(xr), 0, w - 1).astype(int)]
        ok &= ~(twin > dl[yy, xx] + 1.0)  # the right view sees something nearer there
    yy, xx, xr = yy[ok], xx[ok], xr[ok]
    x0 = np.floor(xr).astype(int)
    return yy, xx, x0, xr - x0


def psnr_db(estimate, truth, peak: float = 255.0) -> float:
    """Peak signal-to-noise ratio (dB) of ``estimate`` against ``truth`` (same shape)."""
    e = np.asarray(estimate, dtype=np.float64) - np.asarray(truth, dtype=np.float64)
    mse = float(np.mean(e * e))
    return float("inf") if mse == 0 else 10.0 * np.log10(peak * peak / mse)


def rig_views(dense, rig, split: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The separated left and right views (float64, grey levels) of the complex image behind ``dense`` (a
    :class:`psvs.dense.build.RigDense`; :func:`separate_views` from its maps): on a build each on its own
    view's rectified grid (H', W'), else (H, W). ``rig``: the rig the maps were made through (its split and the
    prior's pixel scale; None: an image without a rig, split 0.5), ``split`` instead of the rig's."""
    res = dense.result
    s = split if split is not None else (rig.mirrors.split_ratio if rig is not None else 0.5)
    if dense.rect is not None and dense.image is None:
        raise ValueError("the views of a build's maps need the complex image they were made of (RigDense.image)")
    seen = dense.left_image if dense.rect is None else dense.image
    k = pixel_scale(rig.camera) if rig is not None and dense.rect is None else None
    return separate_views(seen, res.disparity_left, s, res.disparity_right, rect=dense.rect,
                          pixel_scale=k)   # the prior in scene terms (psvs.dense.separate)

