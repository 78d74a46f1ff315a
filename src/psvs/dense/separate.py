"""Separate a complex image into its left and right views, given the left view's disparity.

Unknowns: the two views L and R (H, W). Least squares of three terms, solved by conjugate gradients:

* data       C = (1 − s)·L + s·R                    (the complex image, per pixel)
* coupling   R(x − d(x)) = L(x)                      (each left-view point seen again by the right view,
                                                      linear interpolation for sub-pixel d; skipped where
                                                      the right map says the twin is occluded)
* prior      λ·(|∇L|² + |∇R|²)                       (the null space of the mixing is an oscillation of
                                                      period 2d/(2k+1): the smoothness prior picks the
                                                      least-oscillating answer)
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from psvs.dense.disparity import check_image


def _differences(h: int, w: int, offset: int, n_unknowns: int) -> sp.csr_matrix:
    idx = np.arange(h * w).reshape(h, w)
    blocks = []
    for a, b in ((idx[:, 1:], idx[:, :-1]), (idx[1:, :], idx[:-1, :])):
        a, b = a.ravel() + offset, b.ravel() + offset
        r = np.arange(a.size)
        blocks.append(sp.csr_matrix((np.r_[np.ones(a.size), -np.ones(a.size)], (np.r_[r, r], np.r_[a, b])),
                                    shape=(a.size, n_unknowns)))
    return sp.vstack(blocks).tocsr()


def _sampling(uv: np.ndarray, h: int, w: int) -> sp.csr_matrix:
    """(N, h*w) bilinear interpolation weights of the grid (h, w) at points uv (N, 2); rows of points off
    the grid are empty."""
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


def separate_views(image, disparity_left, split: float = 0.5, disparity_right=None, smoothness: float = 0.05,
                   coupling: float = 1.0, iterations: int = 200, rect=None) -> tuple[np.ndarray, np.ndarray]:
    """Left and right views (float64 (H, W), grey levels of the input) of the complex ``image`` (H, W).

    ``disparity_left`` (H, W, px, NaN = unknown) ties each left pixel to its right-view twin;
    ``disparity_right`` (optional, same shape) drops the ties of left pixels whose twin it shows to be a
    different, nearer point (occlusion). ``split`` is s, the right view's share (M1's reflectance).

    ``rect`` (a build, psvs.optics.rectify.Rectification): the maps are on the rectified grids (H', W')
    (psvs.dense.build) and so are the views returned, each on its own view's grid; the data term then
    samples them where each complex-image pixel lies in each view."""
    c = check_image(image)
    dl = np.asarray(disparity_left, dtype=np.float64)
    if not 0.0 < split < 1.0:
        raise ValueError(f"split must lie strictly between 0 and 1, got {split}")
    if rect is None:
        h, w = c.shape
        if dl.shape != c.shape:
            raise ValueError(f"disparity map {dl.shape} does not match the image {c.shape}")
        n = h * w
        k = np.arange(n)
        data = sp.csr_matrix((np.r_[np.full(n, 1 - split), np.full(n, split)], (np.r_[k, k], np.r_[k, k + n])),
                             shape=(n, 2 * n))
        start = np.r_[c.ravel(), c.ravel()]
    else:
        w, h = rect.size_px
        if dl.shape != (h, w):
            raise ValueError(f"disparity map {dl.shape} does not match the rectified grid {(h, w)}")
        n = h * w
        data = sp.hstack([(1 - split) * _sampling(rect.pixel_table("left").reshape(-1, 2), h, w),
                          split * _sampling(rect.pixel_table("right").reshape(-1, 2), h, w)]).tocsr()
        from psvs.dense.build import rectified_images    # (build imports this module's neighbours)
        start = np.concatenate([a.ravel() for a in rectified_images(c, rect)]).astype(np.float64)
    yy, xx = np.nonzero(np.isfinite(dl))
    xr = xx - dl[yy, xx]
    ok = (xr >= 0) & (xr <= w - 1)
    if disparity_right is not None:
        drm = np.asarray(disparity_right, dtype=np.float64)
        twin = drm[yy, np.clip(np.round(xr), 0, w - 1).astype(int)]
        ok &= ~(twin > dl[yy, xx] + 1.0)  # the right view sees something nearer there
    yy, xx, xr = yy[ok], xx[ok], xr[ok]
    x0 = np.floor(xr).astype(int)
    x1 = np.minimum(x0 + 1, w - 1)
    f = xr - x0
    m = yy.size
    r = np.arange(m)
    ties = sp.csr_matrix((np.r_[-np.ones(m), 1 - f, f], (np.r_[r, r, r],
                                                         np.r_[yy * w + xx, n + yy * w + x0, n + yy * w + x1])),
                         shape=(m, 2 * n))
    grad = sp.vstack([_differences(h, w, 0, 2 * n), _differences(h, w, n, 2 * n)]).tocsr()
    normal = (data.T @ data + coupling * (ties.T @ ties) + smoothness * (grad.T @ grad)).tocsr()
    rhs = data.T @ c.ravel()
    x, _ = spl.cg(normal, rhs, x0=start, maxiter=iterations, rtol=1e-7)
    return x[:n].reshape(h, w), x[n:].reshape(h, w)


def psnr_db(estimate, truth, peak: float = 255.0) -> float:
    """Peak signal-to-noise ratio (dB) of ``estimate`` against ``truth`` (same shape)."""
    e = np.asarray(estimate, dtype=np.float64) - np.asarray(truth, dtype=np.float64)
    mse = float(np.mean(e * e))
    return float("inf") if mse == 0 else 10.0 * np.log10(peak * peak / mse)
