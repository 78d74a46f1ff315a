"""Route of dense disparity: every pixel of the current image's left view matched in the right view
(docs/dense.md), shown as a colour map with its median disparity and depth, optionally with the two views
separated."""
from __future__ import annotations

import numpy as np
from fastapi import APIRouter

from psvs.dense import DEFAULT, FAST, separate_views
from psvs.dense.build import dense_on_rig, rig_cloud
from psvs.imaging.grey import to_grey8
from psvs.optics.illumination import flat_field
from psvs.optics.scale import pixel_scale as camera_pixel_scale
from psvs.web.bodies import DenseBody
from psvs.web.live_runner import DENSE_LOCK
from psvs.web.png import colour_disparity, data_url
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api")


@router.post("/dense")
def dense(body: DenseBody, session: SessionDep):
    """Dense disparity of the current image, its median disparity and depth, and optionally the separated
    views, as PNG data URLs. The library's dense kernels run under DENSE_LOCK (one at a time, with live mode's)."""
    grey, rig = session.still().grey, session.rig
    with DENSE_LOCK:
        dense_res = dense_on_rig(grey, rig, body.near_mm, body.far_mm, params=FAST if body.fast else DEFAULT)
    res = dense_res.result
    lo, hi = res.searched_px
    d = res.disparity_left       # on a build: on the left view's rectified grid
    z = rig_cloud(dense_res, rig).depth_mm
    out = {"disparity_png": data_url(colour_disparity(d, lo, hi)), "range_px": [lo, hi],
           "answered_pct": 100.0 * float(np.mean(np.isfinite(d))),
           "median_disparity_px": float(np.nanmedian(d)) if np.isfinite(d).any() else None,
           "median_z_mm": float(np.nanmedian(z)) if np.isfinite(z).any() else None}
    if body.views and np.isfinite(d).any():
        with DENSE_LOCK:
            k = camera_pixel_scale(rig.camera) if dense_res.rect is None else None   # the prior in scene terms
            lv, rv = separate_views(flat_field(grey, rig.camera), d, rig.mirrors.split_ratio, res.disparity_right,
                                    rect=dense_res.rect, pixel_scale=k)
        out.update(left_png=data_url(to_grey8(lv)), right_png=data_url(to_grey8(rv)))
    return out
