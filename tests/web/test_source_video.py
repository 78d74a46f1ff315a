"""A video chosen in the page (issue 44, item 1: no panel that only says "start psvs with a flag"): sent to
POST /api/source/video, served from then on as ``psvs serve --video`` would (its first frame the current image,
live mode and the capture on its frames in a loop), kept in the app's own folder, removed when the app stops.
Truth: the video's frames read independently with OpenCV."""
import time

import cv2
import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.params import load_rig
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.web import local_client, serving


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    path = tmp_path_factory.mktemp("video") / "run.avi"
    assert main(["simulate", "fig5a", "--rig", "default", "--frames", "3", "--move-mm", "0,0,-40", "--supersample",
                 "1", "-o", str(path)]) == 0
    return path


def _app():
    return create_app(image_source("blank", np.full((480, 640), 90, np.uint8)), load_rig("default"))


def _first_frame(path) -> np.ndarray:
    cap = cv2.VideoCapture(str(path))
    ok, frame = cap.read()
    cap.release()
    assert ok
    return frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)


def test_a_video_sent_by_the_page_is_served_in_a_loop(video):
    app = _app()
    with local_client(app) as c:
        assert c.get("/api/info").json()["source"]["live"] is False
        r = c.post("/api/source/video?name=run.avi", content=video.read_bytes(),
                   headers={"Content-Type": "video/x-msvideo"})
        assert r.status_code == 200, r.json()
        assert r.json()["name"] == "run.avi" and r.json()["live"] is True and r.json()["fps"] > 0
        info = c.get("/api/info").json()["source"]
        assert info["kind"] == "video" and info["live"] is True and info["name"] == "run.avi"
        got = cv2.imdecode(np.frombuffer(c.get("/api/image.png").content, np.uint8), cv2.IMREAD_GRAYSCALE)
        assert np.array_equal(got, _first_frame(video))
        assert c.post("/api/live/start", json={"dense": True, "check": False}).json() == {"running": True}
        t0 = time.monotonic()
        while ((s := c.get("/api/live/state").json()).get("frame") or 0) < 4:       # 3 frames, in a loop
            assert time.monotonic() - t0 < 120 and not s["error"], s
            time.sleep(0.1)
        assert c.post("/api/live/stop").json() == {"running": False}
        folder = app.state.video_folder
        assert [p.suffix for p in folder.iterdir()] == [".avi"]
    assert not folder.exists()            # the app stopped: its videos are gone


@pytest.mark.parametrize("body, kind, said", [(b"", "video/x-msvideo", "the video is empty"),
                                             (b"not a video at all" * 100, "video/mp4",
                                              "cannot open x.mp4: not a video or image sequence"),
                                             (b"x", "text/plain", "takes a video")])
def test_what_is_no_video_is_refused_in_one_line_and_the_source_stays(body, kind, said):
    app = _app()
    with local_client(app) as c:
        r = c.post("/api/source/video?name=x.mp4", content=body, headers={"Content-Type": kind})
        assert r.status_code in (400, 415) and said in r.json()["detail"] and "\n" not in r.json()["detail"], r.json()
        assert c.get("/api/info").json()["source"] == {"kind": "image", "name": "blank", "live": False, "fps": 0.0}
        folder = getattr(app.state, "video_folder", None)
        assert folder is None or list(folder.iterdir()) == []


def test_a_truncated_video_is_refused_at_the_upload(video):
    """Trial 44: the first part of a video (its header declaring all its frames) was taken, and live mode then
    failed on "DamagedVideo: /tmp/psvs-serve-video-..."; now it is read through when sent: refused in one line
    naming the file as the user named it and what is missing, the image served before stays."""
    data = video.read_bytes()
    with local_client(_app()) as c:
        r = c.post("/api/source/video?name=mine.avi", content=data[:len(data) // 2],
                   headers={"Content-Type": "video/x-msvideo"})
        detail = r.json()["detail"]
        assert r.status_code == 400 and "\n" not in detail, r.json()
        assert "mine.avi" in detail and "psvs-serve" not in detail and "DamagedVideo" not in detail, detail
        assert "of the 3 frames its header declares" in detail or "is damaged" in detail, detail
        assert c.get("/api/info").json()["source"]["kind"] == "image"


def test_a_video_of_another_camera_is_refused(tmp_path):
    """Frames of another size than the rig's camera: refused, the image served before stays."""
    path = tmp_path / "small.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 10.0, (320, 240), isColor=False)
    for k in range(3):
        writer.write(np.full((240, 320), 40 * k, np.uint8))
    writer.release()
    with local_client(_app()) as c:
        r = c.post("/api/source/video?name=small.avi", content=path.read_bytes(),
                   headers={"Content-Type": "video/x-msvideo"})
        assert r.status_code == 400 and "frames are 320x240 px, the rig's camera 640x480 px" in r.json()["detail"]
        assert c.get("/api/info").json()["source"]["kind"] == "image"


def test_the_live_step_opens_a_video_and_runs_on_it(page, video):
    with serving(_app()) as url:
        page.goto(url + "/#live")
        page.wait_for_selector("body[data-ready='1']", timeout=60000)
        assert page.is_disabled("#live-start")
        page.set_input_files("#live-video", str(video))
        page.wait_for_function("document.body.dataset.videoDone === '1'", timeout=60000)
        assert "run.avi: served in a loop" in page.inner_text("#video-status")
        assert not page.is_disabled("#live-start") and "run.avi" in page.inner_text("#source")
        page.check("#live-dense")
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-frame').textContent) >= 2", timeout=60000)
        page.click("#live-stop")


def test_a_video_may_be_larger_than_an_image():
    """The body limit is the image's (8 MiB) everywhere but for a video (512 MiB): 9 MiB of bytes reach the video
    route (and are no video), not the upload route."""
    from psvs.web.api_image import MAX_BODY_BYTES
    big = b"\0" * (MAX_BODY_BYTES + 1024 * 1024)
    with local_client(_app()) as c:
        r = c.post("/api/source/video?name=big.avi", content=big, headers={"Content-Type": "video/x-msvideo"})
        assert r.status_code == 400 and "cannot open big.avi" in r.json()["detail"], r.json()
        r = c.post("/api/upload", content=big, headers={"Content-Type": "image/png"})
        assert r.status_code == 413 and r.json()["detail"] == f"request body over {MAX_BODY_BYTES} bytes"
