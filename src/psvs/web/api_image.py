"""Routes of the image and its pipeline: what the page opens with (``/api/info``), the current complex image,
every pipeline stage of it (paper III.3 step 1), and uploading another complex image."""
from __future__ import annotations

import io

import cv2
import numpy as np
from fastapi import APIRouter, Request

from psvs._quiet import c_stderr_captured, library_reason
from psvs.imaging.pipeline import PAPER
from psvs.imaging.steps import STEPS
from psvs.io.image_header import FORMATS, HeaderError, read_header
from psvs.io.images import grey8
from psvs.measure.triangulate import MODELS, default_model
from psvs.optics.illumination import flat_field
from psvs.optics.rectify import needs_rectification
from psvs.optics.rig import MIRROR_NAMES, Rig
from psvs.web.api_match import snap_px
from psvs.web.bodies import PipelineBody
from psvs.web.capture_runner import describe_target
from psvs.web.guard import UPLOAD_TYPES
from psvs.web.png import data_url, png_response
from psvs.web.session import SessionDep

#: Largest request body (an uploaded PNG of a 640x480 grey image is ~0.3 MB); the app's body limit.
MAX_BODY_BYTES = 8 * 1024 * 1024

router = APIRouter(prefix="/api")


def calibration_status(rig: Rig) -> dict:
    """What the page says of the rig: a build (matched on rectified rows) or the paper's geometry, and
    the reprojection RMS of the calibration that wrote it (None for a design)."""
    cal = rig.calibration
    return {"build": needs_rectification(rig), "calibrated": cal is not None,
            "calibration": None if cal is None else {"rms_px": cal.rms_px, "rms_left_px": cal.rms_left_px,
                                                     "rms_right_px": cal.rms_right_px, "images": cal.images,
                                                     "kinds": cal.kinds},
            "default_model": default_model(rig)}


@router.get("/info")
def info(session: SessionDep):
    """The source, the rig, the image size, the paper's pipeline and what the page may choose from."""
    source, rig = session.source, session.rig
    return {"source": {"kind": source.kind, "name": session.still().name, "live": source.live, "fps": source.fps},
            "rig": {"name": session.rig_name, "focal_length_mm": rig.camera.focal_length_mm,
                    "baseline_mm": rig.mirrors.baseline_mm, "plate_thickness_mm": rig.mirrors.plate_thickness_mm,
                    "glass": glass(rig), **calibration_status(rig)},
            "image_size_px": list(session.image_size_px), "pipeline": PAPER.to_dict()["steps"], "models": list(MODELS),
            "steps": sorted(STEPS), "snap_px": snap_px(rig), "max_upload_bytes": MAX_BODY_BYTES,
            "upload_types": list(UPLOAD_TYPES),
            "capture": capture_info(session)}


def glass(rig: Rig) -> list[dict]:
    """The four glasses to cut: each mirror's extent on its plane (along its s axis and its height, mm; None
    where the rig leaves it unbounded) and the thickness (the M1 plate's; None for the front-surface mirrors)."""
    out = []
    for name in MIRROR_NAMES:
        e = rig.mirrors.extent(name)
        out.append({"mirror": name.upper(), "along_mm": None if e is None else float(e.along_mm[1] - e.along_mm[0]),
                    "height_mm": None if e is None else float(e.height_mm[1] - e.height_mm[0]),
                    "thickness_mm": rig.mirrors.plate_thickness_mm if name == "m1" else None})
    return out


def capture_info(session) -> dict | None:
    """The capture panel's card and folder, or None before they are chosen (psvs serve --target --capture-to,
    or in the page)."""
    setup = session.capture.setup
    if setup is None:
        return None
    return {"target": describe_target(setup.target), "folder": setup.folder}


@router.get("/image.png")
def image(session: SessionDep):
    """The current complex image as a grey PNG."""
    return png_response(session.still().grey)


@router.post("/preview")
def preview(body: PipelineBody, session: SessionDep):
    """Every pipeline stage of the current image as a PNG data URL (binary images and the edge map)."""
    # what the matcher sees: the lens's fall-off undone (psvs.optics.illumination)
    _, stages = body.pipeline().run(flat_field(session.still().grey, session.rig.camera), keep=True)
    return {"stages": [{"op": op, "binary": img.dtype == bool, "png": data_url(img)} for op, img in stages]}


def decode_upload(data: bytes, size_px: tuple[int, int]) -> np.ndarray:
    """An image file's bytes (PNG, JPEG, BMP, TIFF or PNM: what the CLI reads) as an (H, W) uint8 grey image of
    ``size_px`` (W, H). Its format and size are read from its header (:func:`psvs.io.image_header.read_header`,
    as the CLI's readers do) and checked before decoding, so a small file cannot decompress into a huge image.
    What a codec prints on a damaged file ("libpng error: Read Error") is caught, not shown on the server's
    terminal, and named in the one-line ValueError."""
    w, h = size_px
    try:
        header = read_header(io.BytesIO(data))
    except HeaderError as exc:
        raise ValueError(f"upload must be a {FORMATS} image ({exc})") from None
    fmt, pw, ph = header.format, header.width, header.height
    if (pw, ph) != (w, h):
        raise ValueError(f"image is {pw}x{ph} px but the rig's camera is {w}x{h} px")
    failure = None
    with c_stderr_captured() as said:
        try:
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error as exc:
            img, failure = None, str(exc)
    if img is None or img.shape[:2] != (h, w):
        reason = library_reason([*said, *([failure] if failure else [])])
        raise ValueError(f"not a readable {fmt} image" + (f" ({reason})" if reason else ""))
    return grey8(img, "uploaded image")   # colour -> luma, 16-bit scaled by its bit depth (as read_grey)


@router.post("/upload")
async def upload(request: Request, session: SessionDep):
    """Replace the complex image by an image file of the rig's size (the raw request body, its type one of
    psvs.web.guard.UPLOAD_TYPES); the last match is forgotten with the image it was of."""
    img = decode_upload(await request.body(), session.image_size_px)
    session.replace_still(img, "uploaded image")
    return {"image_size_px": list(session.image_size_px)}
