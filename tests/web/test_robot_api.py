"""The Robot step's API on a long run's files (synthetic, as psvs.robot.report writes them): more cycles than the
page draws are drawn every k-th, and the last (where the torch stopped) always."""
import csv
import dataclasses
import io
import json

import numpy as np

from psvs.io.params import load_rig
from psvs.robot.controller import TrackConfig
from psvs.robot.run_log import LOG_COLUMNS
from psvs.web.api_robot import MAX_DRAWN
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.web import local_client


def test_a_long_run_is_drawn_every_kth_cycle_and_its_stop():
    n = 2 * MAX_DRAWN + 7                                   # step 3: the last cycle is not on the grid
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LOG_COLUMNS)
    rng = np.random.default_rng(0)
    tcp = np.cumsum(rng.normal(0, 0.1, (n, 3)), axis=0)
    for k in range(n):
        nums = [0.04 * k, 0.4 * k, 10.0, *tcp[k], *tcp[k], *tcp[k], 1, 0.01, 0.02, *[0.1] * 6, 100.0, 5.0, 5.0]
        w.writerow([f"{v:.4f}" for v in nums] + [""])
    report = {"cycles": n, "welded_mm": 1.0, "valid_frames": n, "lateral_mm": {"rms": 0.01, "max": 0.02},
              "vertical_mm": {"rms": 0.01, "max": 0.02}, "stop": {"reason": "weld length reached"},
              "config": dataclasses.asdict(TrackConfig()), "health": None}
    app = create_app(image_source("blank", np.full((480, 640), 90, np.uint8)), load_rig("default"))
    with local_client(app) as c:
        r = c.post("/api/robot/run", json={"log": buf.getvalue(), "report": json.dumps(report)})
        assert r.status_code == 200, r.json()
        d = r.json()
    drawn = list(range(0, n, 3)) + [n - 1]
    assert d["step"] == 3 and len(d["tcp_mm"]) == len(drawn) <= MAX_DRAWN + 1
    np.testing.assert_allclose(d["tcp_mm"], tcp[drawn], atol=1e-4)
    assert d["report"]["health"] is None
    arc_on = TrackConfig().arc_on_mm
    assert d["welded"] == [0.4 * k >= arc_on for k in drawn] and any(d["welded"])
    # a run halted before the arc (report.json's stop.arc_struck false): nothing drawn as welded, though the
    # torch braked past the arc's start; a flag that is no boolean is refused
    for struck, status in ((False, 200), ("no", 400)):
        report["stop"]["arc_struck"] = struck
        with local_client(app) as c:
            r = c.post("/api/robot/run", json={"log": buf.getvalue(), "report": json.dumps(report)})
        assert r.status_code == status, r.json()
        assert not any(r.json()["welded"]) if status == 200 else "stop.arc_struck" in r.json()["detail"]
