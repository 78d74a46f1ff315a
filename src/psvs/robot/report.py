"""A run's report: torch deviation from the true seam, cycle times, plots, CSV log, JSON summary."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from psvs.io.atomic import write_atomic
from psvs.io.jsonsafe import json_safe
from psvs.live.log import health_cells
from psvs.robot.loop import TrackRun
from psvs.robot.run_log import HEALTH_LOG_COLUMNS, LOG_COLUMNS
from psvs.robot.workpiece import Workpiece


def deviations(run: TrackRun, workpiece: Workpiece, step_mm: float = 0.02) -> dict:
    """Torch tip minus where it should be (the true seam, ``standoff_mm`` above it) for every cycle:
    lateral (horizontal, across the seam: + to the left of travel) and vertical, mm, with the true seam's
    arc length at the nearest point. Arrays (n_cycles,)."""
    lo, hi = workpiece.x_range_mm
    x = np.arange(lo, hi + step_mm, step_mm)
    seam = workpiece.seam_base(x)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(seam, axis=0), axis=1))])
    tcp = np.array([c.tcp_mm for c in run.cycles])
    lat, ver, s_true = [], [], []
    for p in tcp:
        i = int(np.argmin(np.hypot(seam[:, 0] - p[0], seam[:, 1] - p[1])))
        j = min(i + 1, len(seam) - 1) if i + 1 < len(seam) else i - 1
        t = seam[max(i, j)] - seam[min(i, j)]
        t[2] = 0.0
        t /= np.linalg.norm(t)
        n = np.array([-t[1], t[0], 0.0])
        d = p - (seam[i] + np.array([0.0, 0.0, run.config.standoff_mm]))
        lat.append(float(d @ n))
        ver.append(float(d[2]))
        s_true.append(arc[i])
    return {"lateral_mm": np.array(lat), "vertical_mm": np.array(ver), "seam_arc_mm": np.array(s_true),
            "in_gap": workpiece.in_gap(x[[int(np.argmin(np.abs(arc - s))) for s in s_true]])}


def arc_on(run: TrackRun) -> np.ndarray:
    """Mask (n,) of the cycles with the arc on: the torch at the arc's start (``arc_on_mm``) or beyond, unless
    the run was halted before it got there (``stop.arc_blocked``: the self-check found a drift in the run-in):
    then the arc is never struck, however far the torch brakes past that point."""
    s = np.array([c.s_mm for c in run.cycles])
    if run.stop.arc_blocked:
        return np.zeros(len(s), bool)
    return s >= run.config.arc_on_mm


def summary(run: TrackRun, workpiece: Workpiece) -> dict:
    """Numbers of the run: deviations over the welded part (arc on, outside seam gaps), cycle times, stop."""
    dev = deviations(run, workpiece)
    s = np.array([c.s_mm for c in run.cycles])
    weld = arc_on(run)
    scored = weld & ~dev["in_gap"]
    lat, ver = dev["lateral_mm"][scored], dev["vertical_mm"][scored]
    gap = weld & dev["in_gap"]

    def stats(a):
        return {"rms": float(np.sqrt(np.mean(a ** 2))) if len(a) else None,
                "max": float(np.max(np.abs(a))) if len(a) else None}

    def times(name):
        a = np.array([getattr(c, name) for c in run.cycles]) * 1e3
        return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "max": float(a.max())}

    qdd = np.max([c.qdd_peak for c in run.cycles], axis=0)
    dq = np.max(np.abs(np.diff([c.q for c in run.cycles], axis=0)), axis=0) if len(run.cycles) > 1 else np.zeros(6)
    st = run.stop
    return {
        "config": _fields(run.config), "simulation": _fields(run.simulation, skip=("limits",)),
        "cycles": len(run.cycles), "simulated_s": run.cycles[-1].t_s + 1 / run.config.rate_hz,
        "start_s": run.start_s,
        "welded_mm": float(max(0.0, s[-1] - run.config.arc_on_mm)) if weld.any() else 0.0,
        "valid_frames": int(sum(c.valid for c in run.cycles)),
        "lateral_mm": stats(lat), "vertical_mm": stats(ver),
        "in_gap_lateral_mm": stats(dev["lateral_mm"][gap]), "in_gap_vertical_mm": stats(dev["vertical_mm"][gap]),
        "wall_ms": {"render (simulation)": times("wall_render_s"), "sensor": times("wall_sensor_s"),
                    "control": times("wall_control_s")},
        "joints": {"max_step_per_cycle_rad": dq.tolist(), "max_accel_rad_s2": qdd.tolist()},
        "handeye": {"target_fit_rms_mm": run.handeye.target_rms_mm.tolist(),
                    "consistency_mm": run.handeye.spread_mm, "consistency_rad": run.handeye.spread_rad,
                    "error_vs_true_mm": (run.handeye.cam2flange[:3, 3] - run.cam2flange_true[:3, 3]).tolist(),
                    "cam2flange": run.handeye.cam2flange.tolist()},
        "seed_px": list(run.seed_px or ()),
        "stop": {"reason": st.reason, "torch_s_mm": st.s_mm, "torch_mm": st.tcp_mm.tolist(),
                 "last_seen_s_mm": st.last_seen_s_mm, "last_seen_mm": st.last_seen_mm.tolist(),
                 "lost_at_torch_s_mm": st.lost_at_s_mm, "decided_at_torch_s_mm": st.decided_at_s_mm,
                 "arc_struck": bool(weld.any())},
        "gaps_bridged_mm": [[a, b] for a, b in run.gaps_bridged],
        "health": run.health,
    }


def _fields(record, skip: tuple[str, ...] = ()) -> dict:
    """A settings dataclass as a plain dict (for the report)."""
    return {k: getattr(record, k) for k in record.__dataclass_fields__ if k not in skip}


def log_csv(run: TrackRun, workpiece: Workpiece) -> str:
    """One row per control cycle (:data:`psvs.robot.run_log.LOG_COLUMNS`, and ``HEALTH_LOG_COLUMNS`` when the
    self-check ran; read back by :func:`psvs.robot.run_log.read_log_csv`)."""
    dev = deviations(run, workpiece)
    checked = run.health is not None
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LOG_COLUMNS + (HEALTH_LOG_COLUMNS if checked else ()))
    for i, c in enumerate(run.cycles):
        w.writerow([f"{c.t_s:.3f}", f"{c.s_mm:.4f}", f"{c.speed_mm_s:.3f}", *(f"{v:.4f}" for v in c.tcp_mm),
                    *(f"{v:.4f}" for v in c.target_mm), *(f"{v:.4f}" for v in c.seam_mm), int(c.valid),
                    f"{dev['lateral_mm'][i]:.4f}", f"{dev['vertical_mm'][i]:.4f}", *(f"{v:.6f}" for v in c.q),
                    f"{c.wall_render_s * 1e3:.2f}", f"{c.wall_sensor_s * 1e3:.2f}", f"{c.wall_control_s * 1e3:.2f}",
                    c.reason, *(health_cells(c.health and c.health.check).split(",") if checked else ())])
    return buf.getvalue()


def plots(run: TrackRun, workpiece: Workpiece, out_dir: Path) -> None:
    """top_view.png (true seam, followed torch path, where it stopped) and error.png (deviation vs arc
    length)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    dev = deviations(run, workpiece)
    lo, hi = workpiece.x_range_mm
    seam = workpiece.seam_base(np.linspace(lo, hi, 600))
    tcp = np.array([c.tcp_mm for c in run.cycles])
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(seam[:, 0], seam[:, 1], "k-", lw=1, label="true seam")
    ax.plot(tcp[:, 0], tcp[:, 1], "r-", lw=1, label="torch tip followed")
    ax.plot(*run.stop.tcp_mm[:2], "rs", label="stop")
    ax.set_xlabel("base x (mm)"), ax.set_ylabel("base y (mm)"), ax.legend()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("top view")
    _save(fig, out_dir / "top_view.png")
    fig, ax = plt.subplots(figsize=(8, 4))
    s_mm, lateral, vertical = error_series(run, dev)
    ax.plot(s_mm, lateral, label="lateral")
    ax.plot(s_mm, vertical, label="vertical")
    ax.axvline(run.stop.s_mm, color="r", lw=0.8, ls="--", label=f"stop (s = {run.stop.s_mm:.1f} mm)")
    ax.set_xlabel("torch position s along its path (mm; the s of 'torch at s = ...')")
    ax.set_ylabel("torch deviation (mm)")
    ax.axhline(0, color="k", lw=0.5), ax.legend(), ax.set_title("deviation from the true seam (arc on)")
    _save(fig, out_dir / "error.png")


def error_series(run: TrackRun, dev: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What error.png plots, arc on: the torch's path position s (mm, the origin of the CLI's "torch at
    s = ... mm" and of the report's ``stop.torch_s_mm``) and the lateral and vertical deviations (mm)."""
    s_mm = np.array([c.s_mm for c in run.cycles])
    weld = arc_on(run)
    return s_mm[weld], dev["lateral_mm"][weld], dev["vertical_mm"][weld]


def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    write_atomic(path, buf.getvalue())


def write_report(run: TrackRun, workpiece: Workpiece, out_dir) -> dict:
    """Write report.json, log.csv, top_view.png, error.png into ``out_dir`` (atomically each); return the
    summary."""
    out_dir = Path(out_dir)
    summ = summary(run, workpiece)
    write_atomic(out_dir / "log.csv", log_csv(run, workpiece))
    plots(run, workpiece, out_dir)
    write_atomic(out_dir / "report.json", json.dumps(json_safe(summ), indent=2, allow_nan=False))
    return summ
