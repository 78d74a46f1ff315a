"""Dense disparity, depth and point cloud of a complex image on any rig, a misaligned build included.

On the paper's geometry the complex image itself is searched (:func:`psvs.dense.disparity.dense_disparity`).
On a build (psvs.optics.rectify.needs_rectification) a point's twin is rows away, so the complex image is
resampled twice, on the left view's and on the right view's rectified grid, and a left-grid patch's twin
is sought along the same row of the right-grid image (the echo becomes a cross-correlation between the
two, docs/dense.md). The maps are then in rectified coordinates: ``disparity_left`` on the left view's
rectified grid (u'_l − u'_r, px), ``disparity_right`` on the right view's; pixels outside a view's field
are NaN. Depth and points come from the exact model of the build: each left-grid pixel and its twin
u' − d on the right grid, triangulated through the build's depth table (:mod:`psvs.dense.depth_table`: the
left view's exact rays tabled once per calibration, within 0.002 mm of tracing both pixels' rays exactly).
The rectification, its remaps and the table are made once per rig content (:mod:`psvs.dense.rig_cache`: in
memory and in the user's cache folder).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.dense.cloud import Cloud, disparity_cloud, pixel_cloud
from psvs.dense.depth_table import exact_points, table_cloud, table_depth
from psvs.dense.disparity import DenseResult, dense_disparity
from psvs.dense.noise import textured_pixels
from psvs.dense.params import DEFAULT, DenseParams
from psvs.dense.rig_cache import depth_table, filled_maps, outside_pixels, rectification
from psvs.dense.trust import EchoTrust, echo_trust
from psvs.dense.workspace import Workspace
from psvs.imaging import noise_level
from psvs.measure.triangulate import default_model
from psvs.optics.illumination import flat_field
from psvs.optics.rectify import Rectification
from psvs.optics.rig import Rig
from psvs.optics.search_range import disparity_range, working_disparities


@dataclass(frozen=True, eq=False)
class RigDense:
    """The dense result, the rectification it is expressed in (None: complex-image coordinates, the
    paper's geometry), the image the left map is aligned with (H', W') (the complex image itself, or its
    left-grid resampling), e.g. for grey levels of the cloud, and on a build the right grid's (None on the
    paper's geometry): the images the maps were made of; on a build, ``image`` the complex image (H, W)
    they were resampled from (as the maps saw it: flat-fielded), whose pixels carry the sensor's own noise;
    ``rig`` and ``range_mm`` (near, far) the rig and working range searched (None when searched by a disparity
    range given in px)."""

    result: DenseResult
    rect: Rectification | None
    left_image: np.ndarray
    right_image: np.ndarray | None = None
    image: np.ndarray | None = None
    rig: Rig | None = None
    range_mm: tuple[float, float] | None = None

    @property
    def asked_px(self) -> tuple[float, float] | None:
        """The disparities (px) the search was asked to cover (the maps' own ``asked_px``; their
        ``searched_px`` may be narrower, a coarse pass pruning it to what the scene shows, and reaches a lag
        beyond each end), which set the scale of the echo test."""
        return self.result.asked_px

    @property
    def working_px(self) -> tuple[float, float] | None:
        """The disparities (px) the working range gives anywhere in the field, traced exactly, without the
        search's margin (:func:`psvs.optics.search_range.working_disparities`): an answer outside them is a
        depth outside ``range_mm``; the asked disparities when the search was given in px."""
        if self.rig is None or self.range_mm is None:
            return self.asked_px
        return working_disparities(self.rig, *self.range_mm, self.rect) or self.asked_px


def rectified_images(image, rect: Rectification,
                     rows: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The complex image (H, W) resampled on the left and on the right view's rectified grid, float32
    (H', W'), or only on its rows r0..r1-1 (``rows`` = (r0, r1)); outside a view's field each pixel repeats
    the nearest inside one (no artificial edge): one remap each through
    :func:`psvs.dense.rig_cache.filled_maps`."""
    img = np.asarray(image, dtype=np.float32)
    band = slice(None) if rows is None else slice(*rows)
    return tuple(cv2.remap(img, *(m[band] for m in filled_maps(rect, view)), cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_REPLICATE) for view in ("left", "right"))


def dense_on_rig(image, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0, *,
                 params: DenseParams = DEFAULT, d_range: tuple[float, float] | None = None,
                 workspace: Workspace | None = None) -> RigDense:
    """Dense disparity of a complex image (H, W) through ``rig``, searching the disparities of its working
    range near..far mm (or ``d_range``, px). See the module docstring for the coordinates of the maps.
    ``params`` (:data:`~psvs.dense.params.DEFAULT`, :data:`~psvs.dense.params.FAST` or your own) and
    ``workspace`` (a live loop): as in :func:`psvs.dense.disparity.dense_disparity`. A lens whose field is
    not flat (the camera's relative illumination) is first undone (:func:`psvs.optics.illumination.flat_field`),
    so the view separation's model C = (1 - s) L + s R holds in the corners as on the axis."""
    image = np.asarray(image)
    w, h = (int(x) for x in rig.camera.image_size_px)
    if image.ndim >= 2 and image.shape[:2] != (h, w):   # another camera's frame: every ray another pixel's
        raise ValueError(f"the image is {image.shape[1]}x{image.shape[0]} px but the rig's camera is {w}x{h} px: "
                         "an image of that camera, or the rig of this one")
    img = flat_field(image, rig.camera)
    rect = rectification(rig, near_mm, far_mm)
    if rect is None:
        lo, hi = d_range or disparity_range(rig, near_mm, far_mm, width_px=img.shape[1])
        return RigDense(dense_disparity(img, lo, hi, params=params, workspace=workspace), None, img, rig=rig,
                        range_mm=None if d_range else (float(near_mm), float(far_mm)))
    a, b = rectified_images(img, rect)
    lo, hi = d_range or disparity_range(rig, near_mm, far_mm, rect, width_px=a.shape[1])
    hi = min(hi, a.shape[1] - 1.0)
    res = dense_disparity(a, lo, hi, params=params, image_right=b, workspace=workspace)
    # outside a view's field no answer: set in place (the maps dense_disparity returns are its own, float32)
    for view, disparity, confidence in (("left", res.disparity_left, res.confidence_left),
                                        ("right", res.disparity_right, res.confidence_right)):
        outside = outside_pixels(rect, view)
        np.put(disparity, outside, np.nan)
        np.put(confidence, outside, 0.0)
    return RigDense(res, rect, a, b, img, rig=rig, range_mm=None if d_range else (float(near_mm), float(far_mm)))


def rig_trust(dense: RigDense) -> EchoTrust:
    """Which pixels of ``dense`` the echo supports beyond chance (:func:`psvs.dense.trust.echo_trust`), tested
    on the images the maps were made of; on a build, on the two rectified grids, each view's texture counted
    inside its field only, and a pixel's own texture judged on the complex image's pixel it samples
    (:func:`psvs.dense.noise.textured_pixels`); at the scale the asked range sets (:attr:`RigDense.asked_px`),
    whatever the mode pruned it to; no answer trusted outside the disparities the working range gives
    (:attr:`RigDense.working_px`: the searched range's margin holds depths outside it)."""
    if dense.rect is None:
        return echo_trust(dense.left_image, dense.result, scale_range=dense.asked_px, answers_px=dense.working_px)
    inside = tuple(dense.rect.maps(v)[0] >= 0 for v in ("left", "right"))
    textured = noise = None
    if dense.image is not None:     # judged on the camera's pixels: a resampled grid's noise varies with its phase
        noise = noise_level(dense.image)
        own = textured_pixels(dense.image, noise).astype(np.uint8)
        textured = tuple(cv2.remap(own, *filled_maps(dense.rect, view), cv2.INTER_NEAREST,
                                   borderMode=cv2.BORDER_CONSTANT) > 0 for view in ("left", "right"))
    return echo_trust(dense.left_image, dense.result, image_right=dense.right_image, inside=inside,
                      textured=textured, noise=noise, scale_range=dense.asked_px, answers_px=dense.working_px)


def rig_cloud(dense: RigDense, rig: Rig, model: str | None = None, mask=None) -> Cloud:
    """Depth map (on the left map's grid) and point cloud (frame C, mm) of a :class:`RigDense`: on the
    paper's geometry :func:`psvs.dense.cloud.disparity_cloud`; on a build each left-grid pixel (u', v') and
    its twin (u' − d, v') triangulated with ``model`` (default: exact on a build), the exact model through
    the build's depth table (:mod:`psvs.dense.depth_table`; its rectification's own rig), any other by
    mapping both back to the complex image. ``mask`` (H', W' bool) keeps a subset of the map's pixels."""
    model = default_model(rig) if model is None else model
    if dense.rect is None:
        return disparity_cloud(np.asarray(dense.result.disparity_left, dtype=np.float64), rig, model, mask)
    d = dense.result.disparity_left
    rect = dense.rect
    if _through_table(rect, rig, model):
        return Cloud(*table_cloud(depth_table(rect), rect, d, mask))     # one pass over the map
    return pixel_cloud(d, mask, lambda uv, dd: exact_points(rect, uv, dd, model, rig=rig))


def rig_depth(dense: RigDense, rig: Rig, model: str | None = None, mask=None) -> np.ndarray:
    """The depth map of :func:`rig_cloud` (Z, mm, frame C, on the left map's grid, NaN where no point), without
    its point list: on a build with the exact model one pass through the depth table that writes Z alone
    (:func:`psvs.dense.depth_table.table_depth`); otherwise :func:`rig_cloud`'s ``depth_mm``.

    Returns
    -------
    ndarray, shape (H', W'), float64
    """
    model = default_model(rig) if model is None else model
    rect = dense.rect
    if rect is not None and _through_table(rect, rig, model):
        return table_depth(depth_table(rect), rect, dense.result.disparity_left, mask)
    return rig_cloud(dense, rig, model, mask).depth_mm


def _through_table(rect, rig: Rig, model: str) -> bool:
    """Whether ``rect``'s depth table answers for ``rig`` and ``model``: the exact model, through the
    rectification's own camera and mirrors."""
    return model == "exact" and rig.camera == rect.rig.camera and rig.mirrors == rect.rig.mirrors
