"""Adaptive supersampling: the renderer's K x K samples spent only on the pixels that need them.

:func:`psvs.simulate.render.render` traces and shades K x K samples in every pixel of both views. A card or
the accuracy pattern on a plain backdrop is smooth over most of the frame, where one sample gives the same
value. :func:`adaptive_views` first renders each view with one sample a pixel (:func:`one_sample`: traced on
a coarse grid, in full where the grid is not smooth, interpolated where it is), then renders again with the
K x K samples only the pixels that are not smooth there (:func:`rough_pixels`: an edge, a texture, a
shadow, the field's border, and a reach around them), with the renderer's own rays (one sample a pixel: the
cached rays; K x K: those pixels' samples, traced for the frame, not all of the view's) and shading
(:mod:`psvs.simulate.radiance`). Those pixels are the renderer's own; the others differ from its average of
K x K samples by the curvature of a smooth image over a few pixels (1.2e-6 of full well measured, a grey
level being 4e-3). A feature narrower than the coarse grid's diagonal can fall between its points and be
lost: ``render(..., adaptive=True)`` is for scenes whose features are wider than that (:data:`COARSE_STEP_PX`:
3 px; the accuracy pattern's circles and a card's discs are 6 px and more on every rig psvs ships).
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import binary_dilation

from psvs.optics.rig import Rig
from psvs.optics.trace import Rays
from psvs.simulate.geometry import SceneGeometry
from psvs.simulate.kernels import bilinear_fill, not_smooth
from psvs.simulate.radiance import radiance, sample_rays, view_rays
from psvs.simulate.scene import Scene

#: Radiance (1.0 = full well): a pixel whose second difference across it (along a row, a column or a
#: diagonal, in the one-sample render) exceeds this is not smooth. A grey level is 1/255 = 4e-3, the sensor's
#: noise at mid-grey 1e-2; the lamp's fall-off over a plain surface makes second differences of about 1e-8.
SMOOTH_TOL = 1e-5
#: px: how far beyond a pixel that is not smooth supersampling reaches (a feature between two pixel centres,
#: e.g. the edge of the field, shows as a step between them).
ROUGH_REACH_PX = 2
#: px: the grid of the one-sample pass's first look: a feature wider than its diagonal (2.8 px: a disc of
#: 3 px or more, a card, its shadow, the field's border) covers or crosses one of its points.
COARSE_STEP_PX = 2


def rough_pixels(radiance_img: np.ndarray, tol: float = SMOOTH_TOL, reach: int = ROUGH_REACH_PX,
                 border: bool = True) -> np.ndarray:
    """Mask (H, W) of the pixels of a one-sample radiance image (H, W) that are not smooth (their second
    difference along a row, a column or a diagonal above ``tol``), grown by ``reach`` px, and with
    ``border`` the frame's outer ``reach`` px (a feature between a border pixel's centre and its outer edge,
    such as a build's vignetting, has no pixel beyond it to show a step)."""
    img = np.ascontiguousarray(radiance_img, dtype=np.float64)
    rough = np.empty(img.shape, np.uint8)
    not_smooth(img, float(tol), rough)
    if reach == 0:
        return rough.astype(bool)
    if border:                                  # the frame's border: no neighbour beyond it shows a step
        rough[:reach] = rough[-reach:] = 1
        rough[:, :reach] = rough[:, -reach:] = 1
    return cv2.dilate(rough, np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)).astype(bool)


def grid_cells(nodes: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of the ``n`` pixels along an axis, the cell of the coarse grid ``nodes`` (sorted pixel indices,
    at least two) it lies in ((n,) int, clipped to the last cell) and its fraction across that cell ((n,))."""
    cell = np.clip(np.searchsorted(nodes, np.arange(n), side="right") - 1, 0, len(nodes) - 2)
    return cell, (np.arange(n) - nodes[cell]) / (nodes[cell + 1] - nodes[cell])


def _grid(n: int, step: int) -> np.ndarray:
    return np.unique(np.r_[np.arange(0, n, step), n - 1])


def one_sample(geom: SceneGeometry, scene: Scene, rays, size_px, step: int = COARSE_STEP_PX,
               tol: float = SMOOTH_TOL) -> tuple[np.ndarray, float]:
    """One sample a pixel (H, W) of a view (``rays``: its one-sample rays, ``view_rays(rig, 1, view)``), and the
    share of pixels traced: every ``step``-th pixel first; in full, every cell of that grid with a corner that
    is not smooth (its second difference along the grid above ``tol``) and the cells beside it; the
    others, smooth, interpolated bilinearly from their corners (a smooth image's curvature over ``step`` px:
    about 1e-6 of full well)."""
    w, h = size_px
    ys, xs = _grid(h, step), _grid(w, step)
    node = (ys[:, None] * w + xs[None, :]).ravel()
    coarse = radiance(geom, scene, Rays(rays.origins_mm[node], rays.dirs[node], rays.valid[node]))
    coarse = coarse.reshape(len(ys), len(xs))
    rough_node = rough_pixels(coarse, tol, reach=0, border=False)
    rough_cell = rough_node[:-1, :-1] | rough_node[1:, :-1] | rough_node[:-1, 1:] | rough_node[1:, 1:]
    rough_cell = binary_dilation(rough_cell, np.ones((3, 3), bool))
    # bilinear interpolation of the nodes everywhere, then the rough cells traced pixel by pixel
    (iy, fy), (ix, fx) = grid_cells(ys, h), grid_cells(xs, w)
    out, traced = np.empty((h, w)), np.empty((h, w), bool)
    bilinear_fill(coarse, iy, ix, fy, fx, rough_cell, out, traced)
    idx = np.flatnonzero(traced)
    out.ravel()[idx] = radiance(geom, scene, Rays(rays.origins_mm[idx], rays.dirs[idx], rays.valid[idx]))
    out.ravel()[node] = coarse.ravel()
    return out, (len(idx) + node.size) / out.size


def adaptive_views(geom: SceneGeometry, scene: Scene, rig: Rig, supersample: int,
                   step: int = COARSE_STEP_PX) -> tuple[np.ndarray, np.ndarray, float]:
    """Each view's radiance image (H, W), as :func:`psvs.simulate.render.render_views` gives it (K x K samples a
    pixel, K = ``supersample``) wherever the image is not smooth, and the share of its samples traced (module
    docstring); ``step``: the one-sample pass's coarse grid, px."""
    w, h = rig.camera.image_size_px
    k2 = supersample * supersample
    out, shares = [], []
    for view in ("left", "right"):
        one, traced = one_sample(geom, scene, view_rays(rig, 1, view), (w, h), step)
        idx = np.flatnonzero(rough_pixels(one))
        if len(idx):                # only these pixels' samples traced (not the view's every sample, cached)
            fine = radiance(geom, scene, sample_rays(rig, supersample, view, idx))
            one.ravel()[idx] = fine.reshape(-1, k2).mean(axis=1)
        out.append(one)
        shares.append((traced + k2 * len(idx) / one.size) / k2)
    return out[0], out[1], float(np.mean(shares))
