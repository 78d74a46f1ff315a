"""Routes of the rig and its 3-D view: choosing the rig in the page, the layout of the served rig
(:func:`psvs.optics.layout3d.rig_layout`) as JSON, and plotly.js, the WebGL plotting library the page draws it
with, served from the installed ``plotly`` package (nothing is fetched from the internet: the page works
offline)."""
from __future__ import annotations

import importlib.resources

from fastapi import APIRouter, Query
from fastapi.responses import FileResponse, JSONResponse

from psvs.io.jsonsafe import json_safe
from psvs.io.params import load_rig, rig_from_text
from psvs.optics.layout3d import rig_layout
from psvs.optics.layout_check import check_clear
from psvs.rigs import SHIPPED, shipped_rig_path
from psvs.web.bodies import MAX_RANGE_MM, RigChoiceBody
from psvs.web.session import SessionDep

router = APIRouter()

#: plotly.js as the ``plotly`` wheel ships it.
PLOTLY_JS = ("plotly", "package_data/plotly.min.js")


@router.get("/api/rig3d")
def rig3d(session: SessionDep, near_mm: float = Query(400.0, gt=0, le=MAX_RANGE_MM),
          far_mm: float = Query(1200.0, gt=0, le=MAX_RANGE_MM)):
    """The served rig's layout over the working range near_mm..far_mm (mm, frame C; NaN as null)."""
    if not near_mm < far_mm:
        raise ValueError(f"near_mm must be < far_mm, got {near_mm:g} and {far_mm:g}")
    return json_safe(rig_layout(session.rig, near_mm, far_mm))


@router.post("/api/rig")
def choose_rig(body: RigChoiceBody, session: SessionDep):
    """Use another rig from now on: a shipped one by ``name`` or a rig file's ``text`` (a design, or a build
    ``psvs calibrate`` wrote); the served images' size must be its camera's (:meth:`Session.replace_rig`), and
    its layout clear (:func:`psvs.optics.layout_check.check_clear`: 400 naming the blocked path)."""
    if body.name is not None:
        if body.name not in SHIPPED:
            raise ValueError(f"unknown rig name {body.name!r} (shipped: {', '.join(SHIPPED)})")
        rig, name = load_rig(shipped_rig_path(body.name)), body.name
    else:
        rig, name = rig_from_text(body.text, body.file_name or "rig file"), body.file_name or "rig file"
    check_clear(rig, name)          # a blocked layout is no build: refused, as every command refuses it
    session.replace_rig(rig, name)
    return {"name": name}


@router.get("/vendor/plotly.min.js", include_in_schema=False)
def plotly_js():
    """plotly.js from the installed package (cached by the browser for a day); 404 when it is missing."""
    try:
        path = importlib.resources.files(PLOTLY_JS[0]).joinpath(PLOTLY_JS[1])
    except ModuleNotFoundError:
        path = None
    if path is None or not path.is_file():
        return JSONResponse({"detail": "plotly is not installed: pip install plotly (the 3-D views need it)"},
                            status_code=404)
    return FileResponse(str(path), media_type="text/javascript", headers={"Cache-Control": "max-age=86400"})
