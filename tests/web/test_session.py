"""Each app has its own session: two apps in one process keep their own image, name and last match; the
session reads and writes its image, name and result together, and keeps a result only for its own image."""
import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.web.app import create_app
from psvs.web.bodies import DenseBody, LiveBody, MatchBody
from psvs.web.session import Session
from psvs.web.sources import image_source
from tests.support.web import PNG, local_client


def _squares(level: int) -> np.ndarray:
    """A 640x480 complex image: a bright square and its twin 200 px to the right, on a ``level`` background."""
    img = np.full((480, 640), level, np.uint8)
    cv2.rectangle(img, (100, 200), (160, 260), 220, -1)
    cv2.rectangle(img, (300, 200), (360, 260), 220, -1)
    return img


def _png_of(response) -> np.ndarray:
    assert response.status_code == 200 and response.headers["content-type"] == "image/png"
    return cv2.imdecode(np.frombuffer(response.content, np.uint8), cv2.IMREAD_UNCHANGED)


def test_two_apps_keep_their_own_images_and_results():
    rig = default_rig()
    a_img, b_img = _squares(30), np.full((480, 640), 90, np.uint8)
    with local_client(create_app(image_source("a.png", a_img), rig)) as a, \
            local_client(create_app(image_source("b.png", b_img), rig, "rig b")) as b:
        assert np.array_equal(_png_of(a.get("/api/image.png")), a_img)
        assert np.array_equal(_png_of(b.get("/api/image.png")), b_img)
        assert a.get("/api/info").json()["source"]["name"] == "a.png"
        assert b.get("/api/info").json()["source"]["name"] == "b.png"
        assert [a.get("/api/info").json()["rig"]["name"], b.get("/api/info").json()["rig"]["name"]] == [
            "default rig", "rig b"]
        # a match in one app is that app's last result only
        assert a.post("/api/match", json={}).status_code == 200
        assert a.get("/api/export/csv").status_code == 200 and b.get("/api/export/csv").status_code == 409
        # previews are of each app's own image: b's flat image has no binary content
        a_bin = a.post("/api/preview", json={}).json()["stages"][1]["png"]
        b_bin = b.post("/api/preview", json={}).json()["stages"][1]["png"]
        assert a_bin != b_bin
        # an upload to b replaces b's image only
        _, png = cv2.imencode(".png", _squares(60))
        assert b.post("/api/upload", content=png.tobytes(), headers=PNG).status_code == 200
        assert np.array_equal(_png_of(b.get("/api/image.png")), _squares(60))
        assert np.array_equal(_png_of(a.get("/api/image.png")), a_img)
        assert a.get("/api/info").json()["source"]["name"] == "a.png"
        assert b.get("/api/info").json()["source"]["name"] == "uploaded image"
        assert a.get("/api/export/csv").status_code == 200


def test_upload_forgets_the_last_match(disc_source):
    source, rig = disc_source
    with local_client(create_app(source, rig)) as c:
        assert c.post("/api/match", json={}).status_code == 200
        assert c.get("/api/export/json").status_code == 200
        _, png = cv2.imencode(".png", _squares(30))
        assert c.post("/api/upload", content=png.tobytes(), headers=PNG).status_code == 200
        assert c.get("/api/export/json").status_code == 409


def test_session_keeps_a_result_only_for_its_current_image():
    rig = default_rig()
    session = Session(image_source("a.png", _squares(30)), rig)
    still = session.still()
    assert still.name == "a.png" and still.generation == 0 and session.result() is None
    result = object()
    session.replace_still(_squares(60), "uploaded image")       # the image changed while matching
    assert not session.keep_result(result, still.generation) and session.result() is None
    now = session.still()
    assert now.name == "uploaded image" and now.generation == 1 and np.array_equal(now.grey, _squares(60))
    assert session.keep_result(result, now.generation) and session.result() is result
    session.replace_still(_squares(90), "uploaded image")
    assert session.result() is None
    still = session.still()
    session.replace_rig(default_rig(), "another rig")           # the rig changed while matching
    assert not session.keep_result(result, still.generation) and session.result() is None
    with pytest.raises(ValueError, match="must be a 640x480 uint8 grey image"):
        session.replace_still(np.zeros((10, 10), np.uint8), "small")


def test_bodies_validate_range_and_model_once():
    """The bodies refuse near >= far and an unknown model themselves, with the message the API answers."""
    for body in (MatchBody, LiveBody, DenseBody):
        with pytest.raises(ValueError, match="near_mm must be < far_mm, got 800 and 800"):
            body(near_mm=800, far_mm=800)
    for body in (MatchBody, LiveBody):
        with pytest.raises(ValueError, match="model must be one of paper, refraction, exact, got 'magic'"):
            body(model="magic")
        assert body(model="exact").params().model == "exact"
    assert LiveBody(dense=True, near_mm=300, far_mm=900).model is None


def test_a_reader_started_while_the_source_is_replaced_reads_the_new_one():
    """A video opened in the page while another request starts live mode: the start waits for the
    replacement (the session's source lock), so live mode never runs on the source just replaced."""
    import threading
    import time

    from psvs.web.live_runner import LiveRunner

    started, stopping = [], threading.Event()

    class SlowStop(LiveRunner):
        def stop(self):
            stopping.set()
            time.sleep(0.3)          # the replacement is under way: a start now must wait for it
            super().stop()

        def start(self, source, tracker, dense=None, health=None):
            started.append(source.name)

    old, new = image_source("old.png", _squares(30)), image_source("new.png", _squares(90))
    session = Session(old, default_rig(), live=SlowStop())
    replacing = threading.Thread(target=session.replace_source, args=(new,))
    replacing.start()
    assert stopping.wait(5)
    session.start_live(None, None, None)
    replacing.join(5)
    assert started == ["new.png"] and session.still().name == "new.png"


def test_a_stopped_loop_still_in_a_long_step_keeps_the_source_from_being_replaced():
    """A loop that does not return within the stop's wait (a first compile, a long dense step) may still hold its
    camera: the runner says it is finishing, and opening another source is refused in one line until it ends."""
    import threading

    from psvs.web.runner import BackgroundRunner

    class Slow(BackgroundRunner):
        STOP_TIMEOUT_S = 0.05

    release = threading.Event()
    runner = Slow()
    runner._start_loop(lambda: (iter(()),), lambda frames: release.wait(10), "slow")
    runner.stop()
    assert not runner.running and runner.finishing
    release.set()
    for _ in range(200):
        if not runner.finishing:
            break
        threading.Event().wait(0.01)
    assert not runner.finishing
