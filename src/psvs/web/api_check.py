"""Route of the workflow's Check step: the self-check of the calibration on the current image (``psvs check``
on one frame, docs/health.md): how far the twins stand off their rows, on how many tiles, the verdict, and
which mirrors' tilts best explain a drift; a picture of the field where it judged."""
from __future__ import annotations

import base64

from fastapi import APIRouter

from psvs.health import check_frames, explain_drift, explanation_line, offset_figure
from psvs.web.bodies import CheckBody
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api")


@router.post("/check")
def check(body: CheckBody, session: SessionDep):
    """``psvs check --json`` of the current image through the app's rig: :meth:`HealthCheck.as_dict`, the
    mirrors' tilts that best explain a drift (``explained_by`` and its one line ``explanation``, empty when
    healthy), and the field's map as a PNG in base64 (``map_png``; None when it cannot judge)."""
    still = session.still()
    rig = session.rig
    result = check_frames([still.grey], rig, body.near_mm, body.far_mm, body.tolerance_px)
    explained = explain_drift(result, rig, body.near_mm, body.far_mm)
    picture = None if result.verdict == "cannot judge" else base64.b64encode(offset_figure(result)).decode("ascii")
    return result.as_dict() | {
        "image": still.name,
        "explained_by": [e.as_dict() for e in explained],
        "explanation": explanation_line(explained, result.tolerance_px) if explained else "",
        "map_png": picture}
