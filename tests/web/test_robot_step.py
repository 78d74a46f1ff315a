"""The workflow's Robot step (issue 44): a seam-tracking run as ``psvs track`` wrote it, opened in the page:
the seam the sensor measured and the torch's path in 3-D, with the run's own figures (report.json's, as the
command printed them). Truth: the run's files themselves, read independently (csv, json)."""
import csv
import json

import cv2
import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.params import load_rig
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.browser import shot
from tests.support.web import local_client, serving

pytestmark = pytest.mark.slow        # one short tracking run (about 100 rendered cycles)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("track") / "run"
    assert main(["track", "weld_seam", "--rig", "default", "--speed", "20", "--length", "5", "--no-bag",
                 "-o", str(out)]) == 0
    return out


def _app():
    return create_app(image_source("blank", np.full((480, 640), 90, np.uint8)), load_rig("default"))


def test_the_run_reads_back_as_written(run_dir):
    log, report = (run_dir / "log.csv").read_text(), (run_dir / "report.json").read_text()
    rows, rep = list(csv.DictReader((run_dir / "log.csv").open())), json.loads(report)
    with local_client(_app()) as c:
        r = c.post("/api/robot/run", json={"log": log, "report": report})
        assert r.status_code == 200, r.json()
        d = r.json()
        assert d["step"] == 1 and len(d["tcp_mm"]) == len(rows) == rep["cycles"]
        np.testing.assert_allclose(d["tcp_mm"], [[float(x[f"tcp_{a}_mm"]) for a in "xyz"] for x in rows], atol=1e-4)
        seen = [x for x in rows if x["valid"] == "1"]
        np.testing.assert_allclose(d["seam_mm"], [[float(x[f"seam_{a}_mm"]) for a in "xyz"] for x in seen], atol=1e-4)
        arc_on = rep["config"]["look_ahead_mm"] + 10.0                    # psvs.robot.controller.TrackConfig
        assert d["welded"] == [float(x["s_mm"]) >= arc_on for x in rows] and any(d["welded"])
        assert d["report"]["lateral_mm"] == rep["lateral_mm"] and d["report"]["stop"] == rep["stop"]["reason"]
        # the sensor's view at the last cycle: the arm's pose through report.json's hand-eye mounting
        mount = np.array(rep["handeye"]["cam2flange"])
        q = np.array([[float(x[f"q{i + 1}_rad"]) for i in range(6)] for x in rows])
        assert mount.shape == (4, 4) and d["sensor"]["mounting"] == "hand-eye" and d["sensor"]["cycle"] == len(rows) - 1
        from psvs.optics.project import project_points
        from psvs.robot.mounting import tool2flange
        from psvs.robot.view3d import cam2base
        tcp = [float(rows[-1][f"tcp_{a}_mm"]) for a in "xyz"]    # the log's own torch: the arm's frames agree
        np.testing.assert_allclose((cam2base(q[-1], np.eye(4)) @ tool2flange())[:3, 3], tcp, atol=1e-3)
        np.testing.assert_allclose(d["sensor"]["camera"], cam2base(q[-1], mount)[:3, 3], atol=1e-9)
        k = max(i for i, x in enumerate(rows) if x["valid"] == "1")       # the last seam point the sensor measured
        seam = np.array([float(rows[k][f"seam_{a}_mm"]) for a in "xyz"] + [1.0])
        in_c = (np.linalg.inv(cam2base(q[k], mount)) @ seam)[:3]
        for view in ("left", "right"):                                      # lies in both views' fields
            uv, ok = project_points(in_c[None], load_rig("default"), view)
            assert ok[0] and 0 <= uv[0, 0] <= 639 and 0 <= uv[0, 1] <= 479, (view, uv)
        h = rep["health"]                                            # the self-check, on by default
        assert d["report"]["health"] == {k: h[k] for k in ("verdict", "row_offset_rms_px", "uncertainty_px", "steps",
                                                            "cost_pct", "lines")} and h["steps"] >= 1
        # refused in one line: another run's report, a file that is not a log, a report that is not one
        other = json.loads(report)
        other["cycles"] += 1
        for body, said in (({"log": log, "report": json.dumps(other)}, "not one run's files"),
                           ({"log": "a,b\n1,2\n", "report": report}, "log.csv is not a psvs track log"),
                           ({"log": log, "report": "{}"}, "report.json is not a psvs track report"),
                           ({"log": log, "report": "{"}, "report.json is not JSON"),
                           ({"log": log, "report": report.replace(f'"cycles": {rep["cycles"]}', '"cycles": 1e400')},
                            "report.json is not a psvs track report")):
            r = c.post("/api/robot/run", json=body)
            assert r.status_code == 400 and said in r.json()["detail"] and "\n" not in r.json()["detail"], r.json()


def test_the_robot_step_draws_the_run(webgl_page, run_dir):
    rep = json.loads((run_dir / "report.json").read_text())
    with serving(_app()) as url:
        webgl_page.goto(url + "/#robot")
        webgl_page.wait_for_selector("body[data-ready='1']", timeout=60000)
        webgl_page.set_input_files("#robot-run", [str(run_dir / "log.csv"), str(run_dir / "report.json")])
        webgl_page.wait_for_function("document.body.dataset.robotDone === '1'", timeout=60000)
        assert webgl_page.inner_text("#robot-lateral") == (f"{rep['lateral_mm']['rms']:.3f} / "
                                                           f"{rep['lateral_mm']['max']:.3f} mm")
        assert webgl_page.inner_text("#robot-stop") == f"stopped: {rep['stop']['reason']}"
        h = rep["health"]
        said = webgl_page.inner_text("#robot-health")
        assert said.startswith(h["verdict"] or "no step taken")
        assert f"({h['steps']} steps, {h['cost_pct']:.1f} % of the sensor's time)" in said
        assert int(webgl_page.get_attribute("#robot3d", "data-points")) == rep["valid_frames"]
        assert int(webgl_page.get_attribute("#robot3d", "data-sensor")) == rep["cycles"] - 1
        webgl_page.wait_for_selector("#robot3d canvas", timeout=10000)
        drawn = cv2.imdecode(np.frombuffer(webgl_page.locator("#robot3d").screenshot(), np.uint8), cv2.IMREAD_GRAYSCALE)
        assert drawn.std() > 5 and (drawn < 128).mean() > 0.002, drawn.std()     # WebGL drew: not uniform
        shot(webgl_page, "web_robot_step.png")
        # one file alone is not a run
        webgl_page.set_input_files("#robot-run", [str(run_dir / "log.csv")])
        assert "select both files" in webgl_page.inner_text("#robot-status")


def test_the_page_runs_what_psvs_track_runs(run_dir, monkeypatch):
    """POST /api/robot/track runs psvs track's closed loop in the background through the served rig (its hand-eye
    session first, the self-check along): polled until done, its run is the command's with the same speed and
    length, cycle for cycle (report.json's figures, the torch's path). Refused before any work: an unknown
    workpiece, a run beyond the time limit, a second run while one is under way; a run of a rig replaced since
    is not shown."""
    import time

    from psvs import _budget
    rep, rows = json.loads((run_dir / "report.json").read_text()), list(csv.DictReader((run_dir / "log.csv").open()))
    with local_client(_app()) as c:
        assert c.get("/api/robot/track").json() == {"running": False, "cycles": 0, "expected": 0, "error": "",
                                                    "run": None}
        r = c.post("/api/robot/track", json={"scene": "no_such_scene"})
        assert r.status_code == 400 and "no_such_scene" in r.json()["detail"], r.json()
        with monkeypatch.context() as m:
            m.setattr(_budget, "WORK_LIMIT_S", 5.0)          # the session's 3.7 s pass, its 165 cycles not
            r = c.post("/api/robot/track", json={"speed_mm_s": 20, "length_mm": 5})
            assert r.status_code == 400 and r.json()["detail"].startswith("the run: "), r.json()
        r = c.post("/api/robot/track", json={"speed_mm_s": 20, "length_mm": 5})
        assert r.status_code == 200 and r.json()["running"] is True, r.json()
        again = c.post("/api/robot/track", json={"speed_mm_s": 20, "length_mm": 5})
        assert again.status_code == 400 and "under way" in again.json()["detail"]
        t0 = time.monotonic()
        while (st := c.get("/api/robot/track").json())["running"]:
            assert time.monotonic() - t0 < 600
            time.sleep(0.5)
        assert st["error"] == "" and st["cycles"] == rep["cycles"], st
        d = st["run"]
        assert d["report"]["cycles"] == rep["cycles"] and d["report"]["welded_mm"] == rep["welded_mm"]
        assert d["report"]["lateral_mm"] == rep["lateral_mm"] and d["report"]["stop"] == rep["stop"]["reason"]
        np.testing.assert_allclose(d["tcp_mm"], [[float(x[f"tcp_{a}_mm"]) for a in "xyz"] for x in rows], atol=1e-4)
        assert c.post("/api/rig", json={"name": "clear"}).status_code == 200
        assert c.get("/api/robot/track").json()["run"] is None


def test_the_robot_step_runs_a_simulated_weld(webgl_page):
    """A click on Run (25 mm/s, 2 mm: a short run): the page polls the run and draws it, its figures the server's
    run's."""
    import urllib.request
    with serving(_app()) as url:
        webgl_page.goto(url + "/#robot")
        webgl_page.wait_for_selector("body[data-ready='1']", timeout=60000)
        webgl_page.fill("#robot-speed", "25")
        webgl_page.fill("#robot-length", "2")
        webgl_page.click("#robot-track")
        webgl_page.wait_for_function("document.body.dataset.robotDone === '1'", timeout=600000)
        with urllib.request.urlopen(url + "/api/robot/track", timeout=30) as r:
            run = json.load(r)["run"]
        rep = run["report"]
        assert webgl_page.inner_text("#robot-lateral") == (f"{rep['lateral_mm']['rms']:.3f} / "
                                                           f"{rep['lateral_mm']['max']:.3f} mm")
        assert webgl_page.inner_text("#robot-status") == (f"the simulated run through this page's rig: "
                                                          f"{rep['cycles']} cycles")
        assert int(webgl_page.get_attribute("#robot3d", "data-points")) == rep["valid_frames"] > 0
        assert rep["welded_mm"] == pytest.approx(2.0, abs=0.5) and rep["stop"] == "weld length reached"
        webgl_page.wait_for_selector("#robot3d canvas", timeout=10000)
        shot(webgl_page, "web_robot_run.png")
