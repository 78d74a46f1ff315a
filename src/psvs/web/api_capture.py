"""Routes of the capture assistant: choose the card and the folder (or ``psvs serve --target T --capture-to
DIR``), start and stop watching the source for calibration views of the card, and poll the set's progress and
the latest frame."""
from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import JSONResponse

from psvs.calibrate.capture import CaptureParams, check_capture_folder
from psvs.io.atomic import check_output_folder
from psvs.targets.target_file import target_from_text
from psvs.web.bodies import CaptureBody, CaptureSetupBody
from psvs.web.capture_runner import CaptureSetup, describe_target
from psvs.web.png import png_response
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api/capture")


@router.post("/start")
def capture_start(body: CaptureBody, session: SessionDep):
    """Start (or resume) the capture on the source's frames; live mode stops (one reader of the source)."""
    params = CaptureParams(views=body.views, near_mm=body.near_mm, far_mm=body.far_mm)
    session.start_capture(params)
    return {"running": True}


@router.post("/setup")
def capture_setup(body: CaptureSetupBody, session: SessionDep):
    """Choose the card (its target.toml's text) and the folder on this machine the views are saved in: a new
    or empty folder that psvs can write (relative to where psvs serve runs). The card is checked against the
    rig when the capture starts. Answers the folder's full path and the card."""
    target = target_from_text(body.target, "target file")
    try:
        folder = Path(body.folder).expanduser().resolve()
        check_capture_folder(folder)
        check_output_folder(folder, "the capture folder")
        if folder.is_dir() and any(folder.iterdir()):
            raise ValueError(f"the capture folder {str(folder)[:80]} holds files: give a new or empty folder")
    except PermissionError as exc:
        raise ValueError(str(exc)) from None
    except (OSError, RuntimeError) as exc:          # a name too long, ~nosuchuser
        raise ValueError(f"the capture folder {body.folder[:80]!r} cannot be used: "
                         f"{getattr(exc, 'strerror', None) or exc}") from None
    session.capture.configure(CaptureSetup(target, body.target.encode(), str(folder)))
    return {"folder": str(folder), "target": describe_target(target)}


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
