"""Routes of the served source chosen in the page: a camera found on this machine (``POST /api/cameras``, the list
``psvs cameras`` prints; ``/api/source/camera``, as ``psvs serve --camera`` would), or a local video file (any
format psvs reads: AVI, MKV, MP4, MOV; an FFV1 AVI as ``psvs simulate --frames`` writes), sent by the page and
played in a loop for the Live and Capture & calibrate steps, as ``psvs serve --video FILE`` would. The file is
kept in a folder of the app's own, removed when the app stops (or when another video replaces it)."""
from __future__ import annotations

import dataclasses
import re
import shutil
import tempfile
import uuid
from pathlib import Path

from fastapi import APIRouter, Query, Request

from psvs.live.camera import Acquisition, parse_camera, parse_features
from psvs.live.discover import opencv_cameras, vendor_cameras
from psvs.web.bodies import CameraBody, CamerasBody
from psvs.web.session import SessionDep
from psvs.web.sources import camera_source, video_source

router = APIRouter(prefix="/api")

#: Largest video the page may send (bytes): about a minute of 640 x 480 FFV1, or ten seconds at 1440 x 1080.
MAX_VIDEO_BYTES = 512 * 1024 * 1024
#: The suffixes a sent video keeps (the reader goes by it); any other is stored as .avi.
SUFFIXES = (".avi", ".mkv", ".mp4", ".mov", ".webm")


def _folder(app) -> Path:
    """The app's own folder for sent videos (``app.state.video_folder``, made on first use)."""
    if getattr(app.state, "video_folder", None) is None:
        app.state.video_folder = Path(tempfile.mkdtemp(prefix="psvs-serve-video-"))
    return app.state.video_folder


def remove_videos(app) -> None:
    """Remove the app's sent videos (its shutdown)."""
    folder = getattr(app.state, "video_folder", None)
    if folder is not None:
        shutil.rmtree(folder, ignore_errors=True)
        app.state.video_folder = None


@router.post("/source/video")
async def source_video(request: Request, session: SessionDep, name: str = Query("video.avi", max_length=200)):
    """Serve the video in the request's body from now on (its file ``name`` as the user chose it): its first
    frame becomes the current image, live mode and the capture read its frames in a loop. Refused in one line
    (400) when no frame can be read or its frames are not the rig's camera's size; the video served before
    stays then."""
    data = await request.body()
    if not data:
        raise ValueError("the video is empty")
    shown = re.sub(r"[^\w.\- ]", "_", Path(name).name)[:80] or "video"
    suffix = Path(shown).suffix.lower()
    folder = _folder(request.app)
    path = folder / f"{uuid.uuid4().hex}{suffix if suffix in SUFFIXES else '.avi'}"    # never the served one
    path.write_bytes(data)
    try:
        try:
            source = dataclasses.replace(video_source(str(path)), name=shown)
        except (ValueError, OSError) as exc:          # said of the user's file, not of the app's copy
            raise ValueError(str(exc).replace(str(path), shown)) from None
        session.replace_source(source)
    except BaseException:
        path.unlink(missing_ok=True)
        raise
    for old in path.parent.iterdir():        # the video served before is not read any more
        if old != path:
            old.unlink(missing_ok=True)
    return {"kind": source.kind, "name": shown, "fps": source.fps, "live": source.live}


@router.post("/cameras")
def cameras(body: CamerasBody):
    """The cameras this machine has that psvs can open (:mod:`psvs.live.discover`): ``cameras`` [{``spec``,
    ``alias``, ``label``}] (machine-vision cameras first, then the OpenCV indices that open unless ``opencv``
    is false) and ``missing``: a line per vendor whose SDK is not installed. A POST, guarded as every action
    is (psvs.web.guard): finding OpenCV cameras opens each device, which no other page may make it do."""
    found, missing = vendor_cameras()
    if body.opencv:
        found += opencv_cameras()
    return {"cameras": [{"spec": c.spec, "alias": c.alias, "label": c.label} for c in found], "missing": missing}


@router.post("/source/camera")
def source_camera(body: CameraBody, session: SessionDep):
    """Serve the camera ``body`` names from now on, configured with its settings: its first frame becomes the
    current image, live mode and the capture read its frames. Refused in one line (400), the source served
    before kept: an unknown spec, settings for an OpenCV camera (it takes none), a camera that does not open
    or gives no frame, frames not the rig's camera's size."""
    spec = parse_camera(body.camera)
    acquisition = Acquisition(exposure_us=body.exposure_us, gain_db=body.gain_db, trigger=body.trigger,
                              features=parse_features(body.features, "a camera feature"))
    if spec.kind == "opencv" and acquisition.asks_anything():
        raise ValueError(f"camera {spec} is an OpenCV camera: it takes no acquisition settings (exposure, gain, "
                         "trigger, features are for a machine-vision camera)")

    def opened():
        try:
            return camera_source(spec, acquisition)
        except OSError as exc:            # the camera's own words, one line, as a refused value
            raise ValueError(str(exc).strip().splitlines()[0] if str(exc).strip() else f"camera {spec}: "
                             f"{type(exc).__name__}") from None
    source = session.open_source(opened)
    return {"kind": source.kind, "name": source.name, "fps": source.fps, "live": source.live}
