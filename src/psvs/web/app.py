"""``psvs serve``'s web app: the complex image, the pipeline with live previews, the paper's double-click
matching (III.3 step 2) with Fig. 7c/d- and Fig. 8-like views, automatic pairing, exports and live mode.

Everything the page needs comes from this module's routes and the files in ``static/``; no route takes a
file path, so nothing else on the machine can be read. Request bodies are capped (:class:`BodyLimit`).
"""
from __future__ import annotations

import base64
import contextlib
import struct
import tempfile
import threading
from pathlib import Path

import cv2
import numpy as np
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field

from psvs.dense import DEFAULT, FAST, separate_views
from psvs.dense.build import dense_on_rig, rig_cloud
from psvs.imaging.grey import to_grey8
from psvs.imaging.pipeline import PAPER, make_pipeline
from psvs.imaging.steps import STEPS
from psvs.io.images import grey8
from psvs.live.dense import DenseSensor
from psvs.live.tracker import EdgeTracker, TrackerParams, nearest_edge_pixels
from psvs.match.correspondence import MatchParams, match_image
from psvs.match.export import result_to_dict, write_csv, write_json, write_ply
from psvs.measure.triangulate import MODELS, default_model
from psvs.optics.rectify import needs_rectification
from psvs.optics.rig import Rig
from psvs.web.limits import BodyLimit, check_steps
from psvs.web.live_runner import DENSE_LOCK, LiveRunner
from psvs.web.sources import Source

STATIC = Path(__file__).resolve().parent / "static"
#: Largest request body (an uploaded PNG of a 640x480 grey image is ~0.3 MB).
MAX_BODY_BYTES = 8 * 1024 * 1024
#: A double-click this close (px) to an edge selects it.
SNAP_PX = 6.0
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
EXPORTS = {"csv": (write_csv, "text/csv"), "json": (write_json, "application/json"), "ply": (write_ply, "text/plain")}


class PipelineBody(BaseModel):
    model_config = ConfigDict(extra="forbid")
    steps: list[dict] | None = Field(default=None, description="pipeline steps; default: the paper's")


class MatchBody(PipelineBody):
    seed: tuple[float, float] | None = Field(default=None, description="double-clicked (u, v) px; None: automatic")
    near_mm: float = Field(400.0, gt=0, le=100000)
    far_mm: float = Field(1200.0, gt=0, le=100000)
    model: str | None = Field(default=None, description="triangulation model; default: refraction on the "
                                                        "paper's geometry, exact on a build")


class LiveBody(MatchBody):
    dense: bool = Field(False, description="also a dense depth map of every frame (the fast mode)")


class DenseBody(BaseModel):
    model_config = ConfigDict(extra="forbid")
    fast: bool = True
    views: bool = Field(False, description="also separate the left and right views (slower)")
    near_mm: float = Field(400.0, gt=0, le=100000)
    far_mm: float = Field(1200.0, gt=0, le=100000)


def _colour_disparity(d: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """A disparity map (H, W) as a BGR colour image: near (large d) bright, no answer black."""
    t = np.clip((np.nan_to_num(d, nan=lo) - lo) / max(hi - lo, 1e-9), 0, 1)
    out = cv2.applyColorMap(np.rint(255 * t).astype(np.uint8), cv2.COLORMAP_INFERNO)
    out[~np.isfinite(d)] = 0
    return out


def _png(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", img.view(np.uint8) * 255 if img.dtype == bool else img)
    if not ok:
        raise ValueError("could not encode the image as PNG")
    return buf.tobytes()


def _data_url(img: np.ndarray) -> str:
    return "data:image/png;base64," + base64.b64encode(_png(img)).decode()


def _pipeline(steps):
    return PAPER if steps is None else make_pipeline(check_steps(steps))


def _calibration_status(rig: Rig) -> dict:
    """What the page says of the rig: a build (matched on rectified rows) or the paper's geometry, and
    the reprojection RMS of the calibration that wrote it (None for a design)."""
    cal = rig.calibration
    return {"build": needs_rectification(rig), "calibrated": cal is not None,
            "calibration": None if cal is None else {"rms_px": cal.rms_px, "rms_left_px": cal.rms_left_px,
                                                     "rms_right_px": cal.rms_right_px, "images": cal.images,
                                                     "kinds": cal.kinds},
            "default_model": default_model(rig)}


def create_app(source: Source, rig: Rig, rig_name: str = "default rig") -> FastAPI:
    """The web app for one source and rig (state is per app: one user, on their own machine). ``rig_name``
    (e.g. the calibrated rig file) is shown with the rig's f, b and plate thickness."""
    w, h = rig.camera.image_size_px
    if source.still.shape != (h, w):
        raise ValueError(f"{source.name} is {source.still.shape[1]}x{source.still.shape[0]} px but the rig's camera "
                         f"is {w}x{h} px")
    live = LiveRunner()

    @contextlib.asynccontextmanager
    async def lifespan(app):
        yield
        live.stop()

    app = FastAPI(title="psvs", docs_url=None, redoc_url=None, openapi_url=None, lifespan=lifespan)
    app.add_middleware(BodyLimit, max_bytes=MAX_BODY_BYTES)
    state = {"still": source.still, "name": source.name, "result": None}
    lock = threading.Lock()
    app.state.live = live

    @app.exception_handler(ValueError)
    @app.exception_handler(TypeError)
    @app.exception_handler(cv2.error)
    async def bad_input(request: Request, exc: Exception):
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        return JSONResponse({"detail": msg[:300]}, status_code=400)

    @app.exception_handler(RequestValidationError)
    async def bad_request(request: Request, exc: RequestValidationError):
        errs = exc.errors()
        where = ".".join(str(x) for x in errs[0].get("loc", ())) if errs else "body"
        return JSONResponse({"detail": f"malformed request: {where}: {errs[0].get('msg', '') if errs else ''}"[:300]},
                            status_code=422)

    @app.get("/", include_in_schema=False)
    def index():
        return FileResponse(STATIC / "index.html", media_type="text/html")

    app.mount("/static", StaticFiles(directory=STATIC), name="static")

    @app.get("/api/info")
    def info():
        return {"source": {"kind": source.kind, "name": state["name"], "live": source.live, "fps": source.fps},
                "rig": {"name": rig_name, "focal_length_mm": rig.camera.focal_length_mm,
                        "baseline_mm": rig.mirrors.baseline_mm, "plate_thickness_mm": rig.mirrors.plate_thickness_mm,
                        **_calibration_status(rig)},
                "image_size_px": [w, h], "pipeline": PAPER.to_dict()["steps"], "models": list(MODELS),
                "steps": sorted(STEPS), "snap_px": SNAP_PX, "max_upload_bytes": MAX_BODY_BYTES}

    @app.get("/api/image.png")
    def image():
        return Response(_png(state["still"]), media_type="image/png", headers={"Cache-Control": "no-store"})

    @app.post("/api/preview")
    def preview(body: PipelineBody):
        """Every pipeline stage of the current image as a PNG data URL (binary images and the edge map)."""
        _, stages = _pipeline(body.steps).run(state["still"], keep=True)
        return {"stages": [{"op": op, "binary": img.dtype == bool, "png": _data_url(img)} for op, img in stages]}

    @app.post("/api/match")
    def match(body: MatchBody):
        """The paper's algorithm from a double-clicked point (snapped to the nearest edge pixel within
        SNAP_PX), or automatic pairing of every edge when no seed is given."""
        if body.model is not None and body.model not in MODELS:
            raise ValueError(f"model must be one of {', '.join(MODELS)}, got {body.model!r}")
        if not body.near_mm < body.far_mm:
            raise ValueError(f"near_mm must be < far_mm, got {body.near_mm} and {body.far_mm}")
        pipeline, grey, seed = _pipeline(body.steps), state["still"], None
        if body.seed is not None:
            u, v = body.seed
            if not (np.isfinite(u) and np.isfinite(v) and -0.5 <= u < w - 0.5 and -0.5 <= v < h - 0.5):
                raise ValueError(f"seed ({u:g}, {v:g}) is outside the {w}x{h} image")
            near = nearest_edge_pixels(pipeline.run(grey), (u, v), SNAP_PX)
            if len(near) == 0:
                raise ValueError(f"no edge within {SNAP_PX:g} px of ({u:.0f}, {v:.0f}): double-click on an edge")
            seed = [int(near[0][0]), int(near[0][1])]
        res = match_image(grey, rig, seed_px=seed, pipeline=pipeline, near_mm=body.near_mm, far_mm=body.far_mm,
                          params=MatchParams(model=body.model))
        with lock:
            state["result"] = res
        return {"seed_px": seed, **result_to_dict(res, decimals=4)}

    @app.post("/api/dense")
    def dense(body: DenseBody):
        """Dense disparity of the current image (docs/dense.md), its median depth, and optionally
        the separated views, as PNG data URLs."""
        if not body.near_mm < body.far_mm:
            raise ValueError(f"near_mm must be < far_mm, got {body.near_mm} and {body.far_mm}")
        grey = state["still"]
        with DENSE_LOCK:
            dense_res = dense_on_rig(grey, rig, body.near_mm, body.far_mm,
                                     params=FAST if body.fast else DEFAULT)
        res = dense_res.result
        lo, hi = res.searched_px
        d = res.disparity_left       # on a build: on the left view's rectified grid
        z = rig_cloud(dense_res, rig).depth_mm
        out = {"disparity_png": _data_url(_colour_disparity(d, lo, hi)), "range_px": [lo, hi],
               "answered_pct": 100.0 * float(np.mean(np.isfinite(d))),
               "median_disparity_px": float(np.nanmedian(d)) if np.isfinite(d).any() else None,
               "median_z_mm": float(np.nanmedian(z)) if np.isfinite(z).any() else None}
        if body.views and np.isfinite(d).any():
            with DENSE_LOCK:
                lv, rv = separate_views(grey, d, rig.mirrors.split_ratio, res.disparity_right, rect=dense_res.rect)
            out.update(left_png=_data_url(to_grey8(lv)), right_png=_data_url(to_grey8(rv)))
        return out

    @app.get("/api/export/{fmt}")
    def export(fmt: str):
        if fmt not in EXPORTS:
            return JSONResponse({"detail": f"export format must be one of {', '.join(EXPORTS)}"}, status_code=404)
        with lock:
            res = state["result"]
        if res is None:
            return JSONResponse({"detail": "nothing to export yet: match an edge first"}, status_code=409)
        writer, media = EXPORTS[fmt]
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / f"psvs_match.{fmt}"
            writer(path, res)
            data = path.read_bytes()
        return Response(data, media_type=media,
                        headers={"Content-Disposition": f'attachment; filename="psvs_match.{fmt}"'})

    @app.post("/api/upload")
    async def upload(request: Request):
        """Replace the complex image by a grey PNG of the rig's size (raw request body)."""
        data = await request.body()
        if not data.startswith(PNG_SIGNATURE) or len(data) < 33 or data[12:16] != b"IHDR":
            raise ValueError("upload must be a PNG image")
        pw, ph = struct.unpack(">II", data[16:24])
        if (pw, ph) != (w, h):     # checked before decoding: no decompression bombs
            raise ValueError(f"image is {pw}x{ph} px but the rig's camera is {w}x{h} px")
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None or img.shape[:2] != (h, w):
            raise ValueError("not a readable PNG image")
        img = grey8(img, "uploaded image")   # colour -> luma, 16-bit scaled by its bit depth (as read_grey)
        with lock:
            state.update(still=img, name="uploaded image", result=None)
        return {"image_size_px": [w, h]}

    @app.post("/api/live/start")
    def live_start(body: LiveBody):
        if body.seed is None and not body.dense:
            raise ValueError("live mode tracks one edge or shows dense depth: double-click an edge first, "
                             "or tick dense")
        if not body.near_mm < body.far_mm:
            raise ValueError(f"near_mm must be < far_mm, got {body.near_mm} and {body.far_mm}")
        tracker = None if body.seed is None else EdgeTracker(
            rig, body.seed, pipeline=_pipeline(body.steps), near_mm=body.near_mm, far_mm=body.far_mm,
            match=MatchParams(model=body.model if body.model in MODELS else None), params=TrackerParams(snap_px=SNAP_PX))
        dense = DenseSensor(rig, body.near_mm, body.far_mm) if body.dense else None
        live.start(source, tracker, dense)
        return {"running": True}

    @app.post("/api/live/stop")
    def live_stop():
        live.stop()
        return {"running": False}

    @app.get("/api/live/state")
    def live_state():
        return live.state()

    @app.get("/api/live/frame.png")
    def live_frame():
        frame = live.frame()
        if frame is None:
            return JSONResponse({"detail": "no live frame yet"}, status_code=404)
        return Response(_png(frame), media_type="image/png", headers={"Cache-Control": "no-store"})

    @app.get("/api/live/dense.png")
    def live_dense():
        d = live.dense()
        if d is None:
            return JSONResponse({"detail": "no dense frame yet: start live with dense"}, status_code=404)
        return Response(_png(_colour_disparity(d.disparity_px, *d.searched_px)), media_type="image/png",
                        headers={"Cache-Control": "no-store"})

    return app
