"""Route of dense disparity: every pixel of the current image's left view matched in the right view
(docs/dense.md), shown as a colour map with its median disparity and depth, the point cloud of the pixels the
echo supports beyond chance (psvs.dense.trust: what the 3-D view draws), optionally with the two views
separated."""
from __future__ import annotations

import numpy as np
from fastapi import APIRouter, Query
from fastapi.responses import JSONResponse, Response

from psvs.dense import DEFAULT, FAST, separate_views
from psvs.dense.build import dense_on_rig, rig_cloud, rig_trust
from psvs.dense.disparity import constant_refusal
from psvs.dense.refusal import nothing_trusted
from psvs.errors import MeasurementError
from psvs.health.check import whole_check_due
from psvs.imaging.block_grid import block_grid_refusal
from psvs.imaging.grey import to_grey8
from psvs.optics.illumination import flat_field
from psvs.optics.scale import pixel_scale as camera_pixel_scale
from psvs.web.bodies import DenseBody
from psvs.web.live_runner import DENSE_LOCK
from psvs.web.png import colour_disparity, data_url
from psvs.web.self_check import drift_refusal
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api")

#: Most points of the cloud sent to the page (evenly subsampled): what a WebGL scatter turns smoothly.
CLOUD_POINTS = 20000
#: The maps a dense run keeps for the page at full resolution (``GET /api/dense/map``): the left view's
#: disparity where the echo supports it (px), its depth there (mm), and the disparity of the pixels answered
#: without that support (px, drawn in grey); NaN elsewhere.
MAPS = ("disparity", "z", "untrusted")


def full_maps(d: np.ndarray, z: np.ndarray, seen: np.ndarray) -> dict:
    """The dense result's maps (H', W') as float32 (:data:`MAPS`): ``d`` the left map (px, NaN where no
    answer), ``z`` its depth (mm), ``seen`` where the echo supports the answer beyond chance."""
    nan = np.float32(np.nan)
    return {"disparity": np.where(seen, d, nan).astype(np.float32),
            "z": np.where(seen & np.isfinite(z), z, nan).astype(np.float32),
            "untrusted": np.where(np.isfinite(d) & ~seen, d, nan).astype(np.float32)}


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
    (``mapped_pct``), the share answered (``answered_pct``, as ``psvs disparity`` counts them: the mapped share
    when the scene's echo stands above chance anywhere, 0 when it does not and the command would refuse), the
    share the echo supports beyond chance (``trusted_pct``), their median disparity and depth (None when none
    is) and point cloud, and optionally the separated views, as PNG data URLs. ``refused``: why no depth is
    given (then nothing is trusted): a JPEG block grid that would pull the answers
    (:func:`psvs.imaging.block_grid.block_grid_refusal`), the image's self-check saying the rig does not fit
    the image (its quick look, and its whole check when that is due: :func:`psvs.health.check.whole_check_due`),
    or nothing the echo supports (:func:`psvs.dense.refusal.nothing_trusted`, ``psvs disparity``'s words); else
    "". The library's dense kernels
    run under DENSE_LOCK (one at a time, with live mode's)."""
    still, rig = session.still(), session.rig
    grey = still.grey
    constant = constant_refusal(grey)        # as psvs disparity: nothing to match, refused before any work
    if constant:
        raise MeasurementError(constant)
    with DENSE_LOCK:
        dense_res = dense_on_rig(grey, rig, body.near_mm, body.far_mm, params=FAST if body.fast else DEFAULT)
    res = dense_res.result
    lo, hi = res.searched_px
    d = res.disparity_left       # on a build: on the left view's rectified grid
    with DENSE_LOCK:
        trust = rig_trust(dense_res)
    trusted = trust.trusted_left
    seen = trusted & np.isfinite(d)          # the medians of what the echo supports: never a noisy median
    refused = block_grid_refusal(grey)      # as psvs disparity: a hard-compressed JPEG's grid pulls the answers
    if not refused:
        refused, look = drift_refusal(still, rig, body.near_mm, body.far_mm, quick=True)
        if not refused and whole_check_due(look, float(np.mean(seen))):
            refused, _ = drift_refusal(still, rig, body.near_mm, body.far_mm)
    refused = refused or nothing_trusted(dense_res, trust)     # as psvs disparity refuses it, in its words
    if refused:                              # as psvs disparity: no depth through a rig the image has left
        seen = np.zeros_like(seen)
    cloud = rig_cloud(dense_res, rig, mask=seen)       # only the trusted pixels are triangulated
    z = cloud.depth_mm
    mapped = 100.0 * float(np.mean(np.isfinite(d)))
    out = {"disparity_png": data_url(colour_disparity(d, lo, hi, trusted=seen)), "range_px": [lo, hi],
           "mapped_pct": mapped, "answered_pct": mapped if seen.any() else 0.0,
           "trusted_pct": 100.0 * float(np.mean(seen)),
           "median_disparity_px": float(np.median(d[seen])) if seen.any() else None,
           "median_z_mm": float(np.nanmedian(z[seen])) if np.isfinite(z[seen]).any() else None,
           "cloud": cloud_for_page(dense_res, cloud), "refused": refused}
    run = session.keep_dense_maps(full_maps(d, z, seen), still.generation)
    out["maps"] = {"shape": list(d.shape), "run": run, "names": list(MAPS)}
    if body.views and np.isfinite(d).any():
        with DENSE_LOCK:
            k = camera_pixel_scale(rig.camera) if dense_res.rect is None else None   # the prior in scene terms
            lv, rv = separate_views(flat_field(grey, rig.camera), d, rig.mirrors.split_ratio, res.disparity_right,
                                    rect=dense_res.rect, pixel_scale=k)
        out.update(left_png=data_url(to_grey8(lv)), right_png=data_url(to_grey8(rv)))
    return out


@router.get("/dense/map")
def dense_map(session: SessionDep, name: str = Query(..., pattern="^(disparity|z|untrusted)$"),
              run: int = Query(...)):
    """One map of the last dense run (:data:`MAPS`) at full resolution, float32 little-endian, row by row (its
    shape in ``X-Shape: H,W`` and in /api/dense's ``maps``): what the page draws and reads under the pointer.
    404 before a dense run of the current image and rig; 409 when ``run`` is not the kept run's (another run
    since, or the image or rig replaced)."""
    maps = session.dense_maps()
    if maps is None:
        return JSONResponse({"detail": "no dense map of the current image: run dense first"}, status_code=404)
    if run != maps["run"]:
        return JSONResponse({"detail": "that dense map is gone: another dense run, or the image or the rig "
                                       "changed since"}, status_code=409)
    a = maps[name]
    return Response(np.ascontiguousarray(a, dtype="<f4").tobytes(), media_type="application/octet-stream",
                    headers={"X-Shape": f"{a.shape[0]},{a.shape[1]}", "Cache-Control": "no-store"})
