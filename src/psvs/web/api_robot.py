"""Routes of the workflow's Robot step: a seam-tracking run as ``psvs track -o RUN`` wrote it (its log.csv and
report.json, chosen in the page from the user's disk), or one the page runs on a simulated cell through the
served rig (``POST /api/robot/track``, then ``GET /api/robot/track`` until it is done), read back for the 3-D view
of the seam the sensor measured and the torch's path, with the run's own figures."""
from __future__ import annotations

import json

import numpy as np
from fastapi import APIRouter

from psvs.io.jsonsafe import json_safe
from psvs.robot.controller import TrackConfig
from psvs.robot.handeye_session import nominal_cam2flange
from psvs.robot.loop import sensor_range, track_cycles
from psvs.robot.run_log import read_log_csv
from psvs.robot.view3d import sensor_view
from psvs.web.bodies import RobotRunBody, RobotTrackBody
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api")

#: Points of each path the page draws at most (every k-th cycle beyond).
MAX_DRAWN = 5000


def _report(text: str) -> dict:
    """report.json's figures the page shows; ValueError naming what is missing."""
    try:
        rep = json.loads(text)
        cfg = TrackConfig(**rep["config"])
        mount = (rep.get("handeye") or {}).get("cam2flange")
        mount = None if mount is None else np.array(mount, dtype=float)
        if mount is not None and (mount.shape != (4, 4) or not np.isfinite(mount).all()):
            raise ValueError("handeye.cam2flange is no 4 x 4 pose")
        out = {"cycles": int(rep["cycles"]), "welded_mm": float(rep["welded_mm"]),
               "valid_frames": int(rep["valid_frames"]), "lateral_mm": rep["lateral_mm"],
               "vertical_mm": rep["vertical_mm"], "stop": rep["stop"]["reason"],
               "arc_struck": _flag(rep["stop"].get("arc_struck", True), "stop.arc_struck"),
               "arc_on_mm": cfg.arc_on_mm, "health": _health(rep.get("health")), "config": cfg,
               "cam2flange": mount}
    except json.JSONDecodeError as exc:
        raise ValueError(f"report.json is not JSON: {exc.msg} at line {exc.lineno}") from None
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"report.json is not a psvs track report: {exc!s} missing or not a number") from None
    return out


def _flag(v, name: str) -> bool:
    """A report's JSON boolean (ValueError naming ``name`` otherwise); reports before it was written hold none."""
    if not isinstance(v, bool):
        raise ValueError(f"{name} {v!r}")
    return v


def _health(h) -> dict | None:
    """report.json's self-check (None: the run had none): verdict, field RMS and uncertainty px (None when it
    could not judge), steps, cost %, the lines it said."""
    if h is None:
        return None
    num = lambda v: None if v is None else float(v)  # noqa: E731
    verdict = h["verdict"]
    if verdict not in (None, "healthy", "drifted", "cannot judge"):
        raise ValueError(f"health.verdict {verdict!r}")
    return {"verdict": verdict, "row_offset_rms_px": num(h["row_offset_rms_px"]),
            "uncertainty_px": num(h["uncertainty_px"]), "steps": int(h["steps"]), "cost_pct": float(h["cost_pct"]),
            "lines": [str(line) for line in h["lines"]]}


@router.post("/robot/run")
def robot_run(body: RobotRunBody, session: SessionDep):
    """The run's 3-D view and figures (:func:`run_view`) of its log.csv and report.json."""
    return run_view(body.log, body.report, session.rig)


@router.post("/robot/track")
def robot_track(body: RobotTrackBody, session: SessionDep):
    """Start a simulated run (``psvs track SCENE --speed --length`` through the served rig, its hand-eye session
    first, the rolling self-check along): refused before any work when it would take too long (psvs._budget) or
    while one runs; answers {running, expected (control cycles)}."""
    from psvs._budget import check_time
    from psvs.robot.budget import check_session_work, default_roi_rows, track_work
    from psvs.robot.loop import SHARE
    from psvs.robot.workpiece import seam_workpiece
    rig = session.rig
    cfg = TrackConfig(speed_mm_s=body.speed_mm_s, weld_length_mm=body.length_mm, roi_rows=default_roi_rows(rig))
    wp = seam_workpiece(body.scene, cfg.camera_distance_mm)
    setup_s = check_session_work(rig, "the page calibrates the hand-eye mounting first; psvs track --handeye FILE "
                                      "skips it")
    seconds, cycles, frames = track_work(rig, cfg, wp.params["length_mm"], body.length_mm, SHARE)
    check_time(setup_s + seconds, f"the run: {cycles} and {frames},", "a higher speed or a shorter length")
    expected = track_cycles(min(body.length_mm, wp.params["length_mm"]), cfg)
    session.tracking.start(rig, cfg, wp, expected)
    return {"running": True, "expected": expected}


@router.get("/robot/track")
def robot_track_state(session: SessionDep):
    """The page's run: {running, cycles, expected, error ('' none), run (its view as ``POST /api/robot/run`` gives
    it, once done; None before, or when the rig changed since it ran)}."""
    st = session.tracking.state()
    files, rig = st.pop("files"), st.pop("rig")
    st["run"] = None
    if files is not None and rig is session.rig:
        st["run"] = run_view(files["log.csv"], files["report.json"], rig)
    return st


def run_view(log_text: str, report_text: str, rig) -> dict:
    """The run's torch path (``tcp_mm``), its targets, the seam points the sensor measured (``seam_mm``, the
    cycles it saw the seam), the lateral deviation of each drawn cycle and whether the arc was on, all in the
    robot's base frame (mm, every k-th cycle when there are more than :data:`MAX_DRAWN`, and the last: where the
    torch stopped); report.json's figures (``report``); and the sensor's view at the last cycle (``sensor``: the
    served rig's camera, its light paths through the glasses and both views' fields over the seam sensor's depths,
    in the base frame, through the arm's pose and report.json's hand-eye mounting, or the bracket drawing's for
    a report without one: :func:`psvs.robot.view3d.sensor_view`). The two files must be of one run."""
    log = read_log_csv(log_text, "log.csv")
    rep = _report(report_text)
    if rep["cycles"] != len(log.t_s):
        raise ValueError(f"log.csv holds {len(log.t_s)} cycles, report.json {rep['cycles']}: not one run's files")
    n = len(log.t_s)
    step = max(1, -(-n // MAX_DRAWN))
    sel = np.unique(np.r_[np.arange(0, n, step), n - 1])
    seen = log.valid[sel]
    welded = log.welded(rep["arc_on_mm"], rep["arc_struck"])[sel]
    cfg, mount = rep.pop("config"), rep.pop("cam2flange")
    mounted = "hand-eye" if mount is not None else "bracket drawing"
    if mount is None:      # a report of before it was written: the bracket drawing's mounting
        mount = nominal_cam2flange(cfg)
    view = sensor_view(log.q_rad[-1], mount, rig, *sensor_range(cfg))
    return {"tcp_mm": log.tcp_mm[sel].round(4).tolist(), "target_mm": log.target_mm[sel].round(4).tolist(),
            "seam_mm": log.seam_mm[sel][seen].round(4).tolist(), "lateral_mm": log.lateral_mm[sel].round(4).tolist(),
            "welded": welded.tolist(), "step": step, "report": rep,
            "sensor": json_safe(view | {"mounting": mounted, "cycle": n - 1})}
