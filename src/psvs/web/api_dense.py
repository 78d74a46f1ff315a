"""Route of dense disparity: every pixel of the current image's left view matched in the right view
(docs/dense.md), shown as a colour map with its median disparity and depth, the point cloud of the pixels the
echo supports beyond chance (psvs.dense.trust: what the 3-D view draws), optionally with the two views
separated."""
from __future__ import annotations

import numpy as np
from fastapi import APIRouter

from psvs.dense import DEFAULT, FAST, separate_views
from psvs.dense.build import dense_on_rig, rig_cloud, rig_trust
from psvs.imaging.grey import to_grey8
from psvs.io.jsonsafe import json_safe
from psvs.optics.illumination import flat_field
from psvs.optics.scale import pixel_scale as camera_pixel_scale
from psvs.web.bodies import DenseBody
from psvs.web.live_runner import DENSE_LOCK
from psvs.web.png import colour_disparity, data_url
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api")

#: Most points of the cloud sent to the page (evenly subsampled): what a WebGL scatter turns smoothly.
CLOUD_POINTS = 20000
#: Most cells of the grid of disparity and depth the page reads under the pointer and draws as its depth map:
#: every pixel of a 640 x 480 map, every 3rd of a 1440 x 1080 one.
POINTER_CELLS = 310_000


def pointer_grid(d: np.ndarray, z: np.ndarray, seen: np.ndarray) -> dict:
    """Every ``step``-th pixel's disparity (px, 0.01) and depth (mm, 0.1) of the map (H', W'), null where the
    echo does not support it beyond chance: what the page shows under the pointer and draws as its maps; and
    ``untrusted_px`` the disparity of the pixels answered but not supported (null elsewhere), drawn as such.
    ``step`` keeps the grid within POINTER_CELLS."""
    step = max(1, int(np.ceil(np.sqrt(d.size / POINTER_CELLS))))
    ds, zs = d[::step, ::step], z[::step, ::step]
    ok = seen[::step, ::step] & np.isfinite(zs)
    return {"step": step, "shape": list(d.shape),
            "disparity_px": np.where(ok, np.round(ds, 2), np.nan),
            "z_mm": np.where(ok, np.round(zs, 1), np.nan),
            "untrusted_px": np.where(np.isfinite(ds) & ~seen[::step, ::step], np.round(ds, 2), np.nan)}


def even_subset(n: int, most: int = CLOUD_POINTS) -> np.ndarray:
    """Indices of at most ``most`` of ``n`` points, evenly spread (all of them when there are fewer)."""
    return np.unique(np.linspace(0, n - 1, min(most, n)).astype(int)) if n else np.zeros(0, int)


def cloud_for_page(dense_res, cloud) -> dict:
    """A cloud's points (frame C, mm, rounded to 0.01) and grey levels, at most CLOUD_POINTS."""
    k = even_subset(len(cloud.points_mm))
    u, v = cloud.pixels[k].T.astype(int) if len(k) else (np.zeros(0, int), np.zeros(0, int))
    grey = np.asarray(dense_res.left_image)[v, u]
    return {"points_mm": np.round(cloud.points_mm[k], 2).tolist(), "grey": np.round(grey, 1).tolist(),
            "of_points": len(cloud.points_mm)}


@router.post("/dense")
def dense(body: DenseBody, session: SessionDep):
    """Dense disparity of the current image, the share of its pixels the map holds a disparity for
    (``mapped_pct``: no measurement by itself) and the share the echo supports beyond chance (``answered_pct``,
    the same as ``trusted_pct``: what the CLI calls answered), their median disparity and depth (None when
    none is) and point cloud, and optionally the separated views, as PNG data URLs. The library's dense
    kernels run under DENSE_LOCK (one at a time, with live mode's)."""
    grey, rig = session.still().grey, session.rig
    with DENSE_LOCK:
        dense_res = dense_on_rig(grey, rig, body.near_mm, body.far_mm, params=FAST if body.fast else DEFAULT)
    res = dense_res.result
    lo, hi = res.searched_px
    d = res.disparity_left       # on a build: on the left view's rectified grid
    with DENSE_LOCK:
        trusted = rig_trust(dense_res).trusted_left
    seen = trusted & np.isfinite(d)          # the medians of what the echo supports: never a noisy median
    cloud = rig_cloud(dense_res, rig, mask=seen)       # only the trusted pixels are triangulated
    z = cloud.depth_mm
    out = {"disparity_png": data_url(colour_disparity(d, lo, hi, trusted=seen)), "range_px": [lo, hi],
           "mapped_pct": 100.0 * float(np.mean(np.isfinite(d))), "answered_pct": 100.0 * float(np.mean(seen)),
           "trusted_pct": 100.0 * float(np.mean(seen)),
           "median_disparity_px": float(np.median(d[seen])) if seen.any() else None,
           "median_z_mm": float(np.nanmedian(z[seen])) if np.isfinite(z[seen]).any() else None,
           "cloud": cloud_for_page(dense_res, cloud), "pointer": json_safe(pointer_grid(d, z, seen))}
    if body.views and np.isfinite(d).any():
        with DENSE_LOCK:
            k = camera_pixel_scale(rig.camera) if dense_res.rect is None else None   # the prior in scene terms
            lv, rv = separate_views(flat_field(grey, rig.camera), d, rig.mirrors.split_ratio, res.disparity_right,
                                    rect=dense_res.rect, pixel_scale=k)
        out.update(left_png=data_url(to_grey8(lv)), right_png=data_url(to_grey8(rv)))
    return out
