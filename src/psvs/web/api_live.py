"""Routes of live mode: start and stop the session's live runner (an edge tracker, dense depth, or both, on
the source's frames), and poll its state, its latest frame and its latest dense map and cloud."""
from __future__ import annotations

import numpy as np
from fastapi import APIRouter
from fastapi.responses import JSONResponse

from psvs.health.check import frame_checker
from psvs.health.rolling import RollingCheck
from psvs.live.dense import DenseSensor
from psvs.live.tracker import EdgeTracker, TrackerParams
from psvs.match.correspondence import MatchParams
from psvs.measure.model_check import check_closed_form
from psvs.web.api_dense import even_subset
from psvs.web.api_match import SNAP_PX
from psvs.web.bodies import LiveBody
from psvs.web.png import colour_disparity, png_response
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api/live")


@router.post("/start")
def live_start(body: LiveBody, session: SessionDep):
    """Start (or restart) live mode: track the edge at ``seed`` and/or compute each frame's dense depth, with
    the rolling self-check unless ``check`` is false (psvs.health.rolling; its state under ``health``). The
    seed snaps within SNAP_PX of the paper's camera, which EdgeTracker scales to the rig's camera (as
    :func:`~psvs.web.api_match.snap_px` does for a double-click). A still image has no frames: the source
    refuses in one line."""
    if body.seed is None and not body.dense:
        raise ValueError("live mode tracks one edge or shows dense depth: double-click an edge first, "
                         "or tick dense")
    rig = session.rig
    check_closed_form(rig, body.model, body.near_mm, body.far_mm)
    tracker = None if body.seed is None else EdgeTracker(
        rig, body.seed, pipeline=body.pipeline(), near_mm=body.near_mm, far_mm=body.far_mm,
        match=MatchParams(model=body.model), params=TrackerParams(snap_px=SNAP_PX),
        frame_check=frame_checker(rig, body.near_mm, body.far_mm))
    dense = DenseSensor(rig, body.near_mm, body.far_mm) if body.dense else None
    health = RollingCheck(rig, body.near_mm, body.far_mm, body.tolerance_px) if body.check else None
    session.start_live(tracker, dense, health)
    return {"running": True}


@router.post("/stop")
def live_stop(session: SessionDep):
    """Stop live mode (the runner joins its thread)."""
    session.live.stop()
    return {"running": False}


@router.get("/state")
def live_state(session: SessionDep):
    """The runner's latest results, frame rate and depth history (:meth:`LiveRunner.state`)."""
    return session.live.state()


@router.get("/frame.png")
def live_frame(session: SessionDep):
    """The latest live frame as a grey PNG; 404 before the first frame."""
    frame = session.live.frame()
    if frame is None:
        return JSONResponse({"detail": "no live frame yet"}, status_code=404)
    return png_response(frame)


@router.get("/dense.png")
def live_dense(session: SessionDep):
    """The latest frame's dense disparity as a colour map, in grey when the scene's echo does not stand above
    chance (no measurement: :class:`psvs.live.dense.DenseFrame` ``supported``); 404 before the first dense
    frame."""
    d = session.live.dense()
    if d is None:
        return JSONResponse({"detail": "no dense frame yet: start live with dense"}, status_code=404)
    return png_response(colour_disparity(d.disparity_px, *d.searched_px, trusted=d.supported))


@router.get("/cloud")
def live_cloud(session: SessionDep):
    """The latest dense frame's point cloud (frame C, mm, rounded to 0.01; at most CLOUD_POINTS of its points,
    evenly): ``frame``, ``points_mm``, ``of_points``. Live mode's points are the pixels of its strided grid that its
    latest echo test (every 30th frame) supported beyond chance and whose answer has held since
    (:mod:`psvs.live.dense`: none without the scene's echo; ``tested`` true). 404 before the first dense frame."""
    d = session.live.dense()
    if d is None:
        return JSONResponse({"detail": "no dense frame yet: start live with dense"}, status_code=404)
    k = even_subset(len(d.points_mm))
    return {"frame": d.frame, "points_mm": np.round(d.points_mm[k], 2).tolist(), "of_points": len(d.points_mm),
            "tested": True}

