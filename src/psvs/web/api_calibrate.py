"""The Capture & calibrate step's calibration (issue 44): ``psvs calibrate`` on a folder of card views (the
capture's, or one the user names), run in the server in the background, from the rig the page uses as the
nominal start; its rig file written beside the views (``build.toml``) and used by every computation after.

- ``POST /api/calibrate`` {folder?}: start (the capture's folder when none is given; refused while one runs or
  while the capture runs);
- ``GET /api/calibrate/state``: {running, folder, error, result}: ``result`` the calibration's figures (the
  reprojection RMS, per view, the images used and skipped, the baseline |O1 O2| with its 1 sigma, the
  parameters the images could not pin, the file written).

A calibration the evidence does not support (psvs.evidence: a rig no build of the design can be, too few
views) is an ``error`` with its one line, and nothing is written or changed.
"""
from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter

from psvs.web.bodies import CalibrateBody
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api/calibrate")


@router.post("")
def calibrate_start(body: CalibrateBody, session: SessionDep):
    """Start calibrating the folder (module docstring); answers {"running": true, "folder"}."""
    if session.capture.running:
        raise ValueError("stop the capture before calibrating")
    if body.folder is None:
        if session.capture.setup is None:
            raise ValueError("choose the capture's card and folder first, or name a folder of card views")
        folder = session.capture.setup.folder
    else:
        folder = body.folder
    try:
        path = Path(folder).expanduser().resolve()
        ok = path.is_dir()
    except (OSError, RuntimeError):
        ok = False
    if not ok:
        raise ValueError(f"no folder of card views at {str(folder)[:200]}")
    session.calibration.start(path, session.rig, lambda rig, p: session.replace_rig(rig, str(p)))
    return {"running": True, "folder": str(path)}


@router.get("/state")
def calibrate_state(session: SessionDep):
    """:meth:`CalibrationJob.state`."""
    return session.calibration.state()
