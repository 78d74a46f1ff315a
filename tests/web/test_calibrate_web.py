"""The Capture & calibrate step's calibration in the page (issue 44): `psvs calibrate` run by the server on a
folder of card views, from the rig in use as the design. Planted truth: simulated hand-held card views of the
misaligned build (`psvs card-views`), calibrated from the clear design; the build's |O1 O2| is known."""
import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.params import load_rig
from psvs.optics.mirrors import virtual_baseline_mm
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.browser import shot
from tests.support.web import local_client, serving


def _app():
    return create_app(image_source("blank", np.full((480, 640), 90, np.uint8)), load_rig("clear"), "clear")


def test_calibrate_refusals(tmp_path):
    """No folder and no capture, a folder that is not one, a folder without card views: one line each, the rig
    in use unchanged."""
    (tmp_path / "empty").mkdir()
    with local_client(_app()) as c:
        r = c.post("/api/calibrate", json={})
        assert r.status_code == 400 and "choose the capture's card and folder first" in r.json()["detail"]
        r = c.post("/api/calibrate", json={"folder": str(tmp_path / "nosuch")})
        assert r.status_code == 400 and r.json()["detail"].startswith("no folder of card views at ")
        assert c.post("/api/calibrate", json={"folder": str(tmp_path / "empty"), "x": 1}).status_code == 422
        assert c.post("/api/calibrate", json={"folder": str(tmp_path / "empty")}).json()["running"] is True
        while (s := c.get("/api/calibrate/state").json())["running"]:
            pass
        assert s["error"] and "\n" not in s["error"] and s["result"] is None, s
        assert c.get("/api/info").json()["rig"]["name"] == "clear" and not (tmp_path / "empty" / "build.toml").exists()


@pytest.mark.slow            # 16 simulated card views and their bundle adjustment
def test_the_page_calibrates_the_views_and_uses_the_build(webgl_page, tmp_path, capsys):
    views = tmp_path / "cards"
    assert main(["card-views", str(views), "--rig", "misaligned", "--views", "16"]) == 0
    capsys.readouterr()
    with serving(_app()) as url:
        page = webgl_page
        page.goto(url + "/#capture")
        page.wait_for_selector("body[data-ready='1']", timeout=60000)
        page.fill("#calibrate-dir", str(views))
        page.click("#calibrate-run")
        page.wait_for_function("document.body.dataset.calibrateDone === '1' || "
                               "document.body.dataset.calibrateDone === 'error'", timeout=400000)
        assert page.evaluate("document.body.dataset.calibrateDone") == "1", page.inner_text("#calibrate-status")
        shot(page, "web_calibrate_step.png")
        state = page.evaluate("fetch('/api/calibrate/state').then(r => r.json())")
        info = page.evaluate("fetch('/api/info').then(r => r.json())")
        shown = {k: page.inner_text(f"#calibrate-{k}") for k in ("rms", "used", "file")}
    res = state["result"]
    file = views / "build.toml"
    assert res["file"] == str(file) and file.is_file() and res["used"] == 16 and res["rms_px"] <= 0.05
    # the file reads back as the rig now in use, and is the build: its |O1 O2| the true build's
    built = load_rig(file)
    assert built.calibration.rms_px == pytest.approx(res["rms_px"], abs=1e-9)
    assert virtual_baseline_mm(built) == pytest.approx(virtual_baseline_mm(load_rig("misaligned")), abs=0.1)
    assert virtual_baseline_mm(built) == pytest.approx(res["baseline_mm"], abs=1e-6)
    assert info["rig"]["name"] == str(file) and info["rig"]["calibration"]["rms_px"] == pytest.approx(res["rms_px"])
    # the page's readout is the state's
    assert shown["rms"].startswith(f"{res['rms_px']:.4f} px (left {res['rms_left_px']:.4f}")
    assert shown["used"].startswith("16 (16 grid)") and shown["file"] == str(file)


def test_a_calibration_never_replaces_a_rig_file_in_the_folder(tmp_path):
    """Issue 41's second trial: the page's calibration replaced a build.toml already in the folder (md5 changed).
    The next free name is taken instead (build-2.toml, build-3.toml ...)."""
    from psvs.web.calibration_job import free_rig_name
    assert free_rig_name(tmp_path / "build.toml") == tmp_path / "build.toml"
    (tmp_path / "build.toml").write_text("mine")
    assert free_rig_name(tmp_path / "build.toml") == tmp_path / "build-2.toml"
    (tmp_path / "build-2.toml").write_text("an earlier calibration")
    assert free_rig_name(tmp_path / "build.toml") == tmp_path / "build-3.toml"
