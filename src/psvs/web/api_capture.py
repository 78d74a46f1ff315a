"""Routes of the capture assistant: start and stop watching the source for calibration views of the card
(``psvs serve --target T --capture-to DIR``), and poll the set's progress and the latest frame."""
from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import JSONResponse

from psvs.calibrate.capture import CaptureParams
from psvs.web.bodies import CaptureBody
from psvs.web.png import png_response
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api/capture")


@router.post("/start")
def capture_start(body: CaptureBody, session: SessionDep):
    """Start (or resume) the capture on the source's frames; live mode stops (one reader of the source)."""
    params = CaptureParams(views=body.views, near_mm=body.near_mm, far_mm=body.far_mm)
    session.live.stop()
    session.capture.start(session.source, session.rig, params)
    return {"running": True}


@router.post("/stop")
def capture_stop(session: SessionDep):
    """POST /api/capture/stop: stop the capture assistant."""
    session.capture.stop()
    return {"running": False}


@router.get("/state")
def capture_state(session: SessionDep):
    """:meth:`psvs.web.capture_runner.CaptureRunner.state`."""
    return session.capture.state()


@router.get("/frame.png")
def capture_frame(session: SessionDep):
    """The latest frame the capture judged, as a grey PNG; 404 before the first."""
    frame = session.capture.frame()
    if frame is None:
        return JSONResponse({"detail": "no capture frame yet"}, status_code=404)
    return png_response(frame)
