"""``psvs serve``'s web app: the complex image, the pipeline with live previews, the paper's double-click
matching (III.3 step 2) with Fig. 7c/d- and Fig. 8-like views, automatic pairing, exports, live mode and the
capture assistant for calibration views.

:func:`create_app` builds one app from a source and a rig. Its routes are grouped by concern in routers
(``api_image``: info, the image, previews, uploads; ``api_match``: matching and exports; ``api_dense``: dense
disparity; ``api_live``: live mode; ``api_capture``: the capture assistant; ``api_adjust``: the alignment
guide of a calibrated build; ``api_rig3d``: the rig's 3-D layout and the plotting library that draws it;
``api_mount``: the mount made in the page, its files and its 3-D mesh)
that read the app's :class:`~psvs.web.session.Session` through FastAPI's
dependency injection, so each app has its own image and results. Everything the page needs comes from these
routes and the files in ``static/``; no route reads a file the user did not name in the page (the folders of the
capture and the calibration, relative to where psvs serve runs; the files the page sends -- an image, a video, a
rig file, a card, a mount, a run's log -- arrive in the request's body).
Request bodies are capped (:class:`~psvs.web.limits.BodyLimit`); bad requests get a 4xx answer with a
one-line ``detail``. Before any of that, :class:`~psvs.web.guard.Guard` lets through only requests that name
the server in their ``Host`` and, when they change something, come from the page itself or carry the per-run
token (:class:`~psvs.web.guard.Access`).
"""
from __future__ import annotations

import contextlib
from pathlib import Path

import cv2
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse
from fastapi.staticfiles import StaticFiles

from psvs.errors import MeasurementError
from psvs.optics.rig import Rig
from psvs.web import (
    api_adjust,
    api_calibrate,
    api_capture,
    api_check,
    api_dense,
    api_image,
    api_live,
    api_match,
    api_mount,
    api_rig3d,
    api_robot,
    api_source,
)
from psvs.web.api_image import MAX_BODY_BYTES
from psvs.web.capture_runner import CaptureRunner, CaptureSetup
from psvs.web.guard import Access, Guard
from psvs.web.limits import BodyLimit
from psvs.web.session import Session
from psvs.web.sources import Source

__all__ = ["MAX_BODY_BYTES", "ROUTERS", "STATIC", "create_app"]

STATIC = Path(__file__).resolve().parent / "static"
#: The routers of the API, one per concern.
ROUTERS = (api_image, api_match, api_dense, api_live, api_capture, api_calibrate, api_adjust, api_rig3d, api_mount,
           api_check, api_robot, api_source)
#: Longest ``detail`` of a 4xx answer (characters).
MAX_DETAIL = 300


def _one_line(exc: BaseException) -> str:
    """The last line of an exception's message (OpenCV's errors span several), or its type's name."""
    text = str(exc).strip()
    return (text.splitlines()[-1] if text else type(exc).__name__)[:MAX_DETAIL]


async def bad_value(request: Request, exc: Exception) -> JSONResponse:
    """A well-formed request with a value the library refuses (ValueError, TypeError, cv2.error): 400."""
    return JSONResponse({"detail": _one_line(exc)}, status_code=400)


async def cannot_measure(request: Request, exc: MeasurementError) -> JSONResponse:
    """A well-formed request whose data cannot give a right answer (MeasurementError, the CLI's exit 1): 422
    "cannot measure: ..." with the reason."""
    return JSONResponse({"detail": f"cannot measure: {_one_line(exc)}"[:MAX_DETAIL]}, status_code=422)


async def bad_request(request: Request, exc: RequestValidationError) -> JSONResponse:
    """A body the models refuse. When every error is a ValueError of a body validator (near_mm >= far_mm, an
    unknown model), the body is well-formed but a value is bad: 400 with the validator's message, as the
    routes answer bad values. Otherwise (bad JSON, a wrong type, a bound, an unknown key): 422 naming where."""
    errs = exc.errors()
    causes = [e.get("ctx", {}).get("error") for e in errs if e.get("type") == "value_error"]
    if errs and len(causes) == len(errs) and all(isinstance(c, ValueError) for c in causes):
        return JSONResponse({"detail": _one_line(causes[0])}, status_code=400)
    where = ".".join(str(x) for x in errs[0].get("loc", ())) if errs else "body"
    detail = f"malformed request: {where}: {errs[0].get('msg', '') if errs else ''}"
    return JSONResponse({"detail": detail[:MAX_DETAIL]}, status_code=422)


def create_app(source: Source, rig: Rig, rig_name: str = "default rig", capture: CaptureSetup | None = None,
               access: Access | None = None) -> FastAPI:
    """The web app for one source and rig.

    Parameters
    ----------
    source : Source
        The still image the page opens with and, unless it is a still image, the frames of live mode. Its
        still must have the rig's image size (ValueError otherwise).
    rig : Rig
        The rig every computation uses.
    rig_name : str
        Shown with the rig's f, b and plate thickness (e.g. the calibrated rig file).
    capture : CaptureSetup, optional
        The card and the folder of the capture assistant (``/api/capture``); without it capture is refused.
    access : Access, optional
        Who may drive it (:class:`~psvs.web.guard.Guard`): the names in ``Host`` and the token. Default: a
        loopback bind's (localhost, 127.0.0.1, ::1 on the port a request arrives on) with a new token.

    Returns
    -------
    FastAPI
        The app, with its own :class:`~psvs.web.session.Session` (``app.state.session``): one user, on their
        own machine. Its live runner and capture stop when the app shuts down. ``app.state.access`` is
        ``access``.
    """
    session = Session(source, rig, rig_name, capture=CaptureRunner(capture))

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI):
        yield
        app.state.session.live.stop()
        app.state.session.capture.stop()
        api_source.remove_videos(app)

    app = FastAPI(title="psvs", docs_url=None, redoc_url=None, openapi_url=None, lifespan=lifespan)
    app.state.session = session
    app.state.access = access or Access.for_bind("127.0.0.1")
    app.add_middleware(BodyLimit, max_bytes=MAX_BODY_BYTES, larger={"/api/source/video": api_source.MAX_VIDEO_BYTES})
    app.add_middleware(Guard, access=app.state.access)     # added last: runs first, before the body is read
    for error in (ValueError, TypeError, cv2.error):
        app.add_exception_handler(error, bad_value)
    app.add_exception_handler(RequestValidationError, bad_request)
    app.add_exception_handler(MeasurementError, cannot_measure)

    @app.get("/", include_in_schema=False)
    def index():
        return FileResponse(STATIC / "index.html", media_type="text/html")

    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    for module in ROUTERS:
        app.include_router(module.router)
    return app
