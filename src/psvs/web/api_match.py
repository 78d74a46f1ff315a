"""Routes of matching and its exports: the paper's double-click matching (III.3 step 2) or automatic pairing
of every edge, and the last match as CSV, JSON or PLY (the writers of ``psvs match``)."""
from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import numpy as np
from fastapi import APIRouter
from fastapi.responses import JSONResponse, Response

from psvs.imaging.pipeline import Pipeline
from psvs.live.tracker import nearest_edge_pixels
from psvs.match.correspondence import match_image, rows_unshown
from psvs.match.export import result_to_dict, write_csv, write_json, write_ply
from psvs.measure.model_check import check_closed_form, model_error_note
from psvs.optics.illumination import flat_field
from psvs.optics.rig import Rig
from psvs.optics.scale import pixel_scale
from psvs.web.bodies import MatchBody
from psvs.web.self_check import drift_refusal
from psvs.web.session import SessionDep

#: A double-click this close to an edge selects it, in px of the paper's camera (1130 px per unit
#: tan(angle)): :func:`snap_px` scales it to the rig's camera, so a click snaps within the same angle
#: (about 0.3°) on a 640x480 and on a 1440x1080 camera.
SNAP_PX = 6.0
EXPORTS = {"csv": (write_csv, "text/csv"), "json": (write_json, "application/json"), "ply": (write_ply, "text/plain")}

router = APIRouter(prefix="/api")


def snap_px(rig: Rig) -> float:
    """The snap radius on ``rig``'s camera, px: :data:`SNAP_PX` times its pixel scale
    (:func:`psvs.optics.scale.pixel_scale`; 6 px on the paper's camera, 12.3 px on mv1440's)."""
    return SNAP_PX * pixel_scale(rig.camera)


def snap_seed(grey: np.ndarray, pipeline: Pipeline, seed: tuple[float, float], radius_px: float = SNAP_PX) -> list[int]:
    """The edge pixel [u, v] of ``pipeline``'s edge map of ``grey`` nearest to a double-clicked ``seed`` (u, v),
    within ``radius_px`` (:func:`snap_px` of the rig); ValueError for a click off the image or off every edge."""
    h, w = grey.shape
    u, v = seed
    if not (np.isfinite(u) and np.isfinite(v) and -0.5 <= u < w - 0.5 and -0.5 <= v < h - 0.5):
        raise ValueError(f"seed ({u:g}, {v:g}) is outside the {w}x{h} image")
    near = nearest_edge_pixels(pipeline.run(grey), (u, v), radius_px)
    if len(near) == 0:
        raise ValueError(f"no edge within {radius_px:.3g} px of ({u:.0f}, {v:.0f}): double-click on an edge")
    return [int(near[0][0]), int(near[0][1])]


@router.post("/match")
def match(body: MatchBody, session: SessionDep):
    """The paper's algorithm from a double-clicked point (snapped to the nearest edge pixel within
    :func:`snap_px` of the rig), or automatic pairing of every edge when no seed is given, with how its twins
    stood against chance (``chance`` {answered, text}; not answered, and why, when the pairs stand off the rig's
    rows: :mod:`psvs.match.rows`) and ``model_note``, what a closed-form model's own depth error on the rig is
    when over 0.5 % ("" otherwise: :func:`psvs.measure.model_check.model_error_note`). The result is kept for the
    exports unless the image was replaced while it was computed."""
    still, pipeline = session.still(), body.pipeline()
    rig = session.rig
    check_closed_form(rig, body.model, body.near_mm, body.far_mm)
    seed = None if body.seed is None else snap_seed(flat_field(still.grey, rig.camera), pipeline, body.seed,
                                                    snap_px(rig))
    res = match_image(still.grey, rig, seed_px=seed, pipeline=pipeline, near_mm=body.near_mm,
                      far_mm=body.far_mm, params=body.params())
    off_rows = res.rows is not None and res.rows.refuses       # the twins stand off the rig's rows
    chance = {"answered": res.chance.answered and not off_rows,
              "text": res.rows.describe() if off_rows else res.chance.describe()}
    if res.edge_noise is not None and res.edge_noise.noise:    # the edges are the sensor's noise: no pair
        chance = {"answered": False, "text": res.edge_noise.describe()}
    if res.pairs:
        drift, check = drift_refusal(still, rig, body.near_mm, body.far_mm)
        drift = drift or rows_unshown(res, check)
        if drift:           # as psvs match: no pair through a rig the image's own twins say it has left, or
            # where neither they nor a pair shows its rows hold
            res = dataclasses.replace(res, pairs=[])
            chance = {"answered": False, "text": drift}
    session.keep_result(res, still.generation)
    # a closed form that reads depth more than 0.5 % off on this rig says so, as the commands do on stderr
    note = model_error_note(rig, body.model, body.near_mm, body.far_mm)
    return {"seed_px": seed, **result_to_dict(res, decimals=4), "chance": chance, "model_note": note}




@router.get("/export/{fmt}")
def export(fmt: str, session: SessionDep):
    """The last match of the current image as a download: 404 for an unknown format, 409 before any match."""
    if fmt not in EXPORTS:
        return JSONResponse({"detail": f"export format must be one of {', '.join(EXPORTS)}"}, status_code=404)
    res = session.result()
    if res is None:
        return JSONResponse({"detail": "nothing to export yet: match an edge first"}, status_code=409)
    writer, media = EXPORTS[fmt]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"psvs_match.{fmt}"
        writer(path, res)
        data = path.read_bytes()
    return Response(data, media_type=media, headers={"Content-Disposition": f'attachment; filename="psvs_match.{fmt}"'})
