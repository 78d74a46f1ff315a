"""``psvs track``: closed-loop seam tracking with the PSVS on a simulated PUMA arm; report, CSV, plots, bag."""
from __future__ import annotations

import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from psvs.cli.common import (
    add_check_arguments,
    add_rig_argument,
    add_telemetry_arguments,
    check_distinct,
    check_telemetry_arguments,
    check_tolerance,
    measuring_rig,
    open_telemetry,
    parse_seed,
)
from psvs.io.atomic import check_output_folder


def add_parser(sub) -> None:
    p = sub.add_parser("track", help="follow a weld seam with the PSVS on a simulated PUMA arm",
                       description="Closed loop in simulated time: every control cycle the complex image (the "
                                   "sensor window) is rendered from the camera pose, both groove edges are "
                                   "matched with their twins and triangulated, the seam path model is updated "
                                   "and the torch follows it. Writes report.json, log.csv, top_view.png, "
                                   "error.png and a ROS 2 bag (bag/) into RUN_DIR. See docs/robot.md.")
    p.add_argument("scene", metavar="SCENE", help="the workpiece: weld_seam[:key=value,...] "
                                                  "(e.g. weld_seam:gap_start_mm=0,gap_length_mm=10)")
    add_rig_argument(p)
    p.add_argument("--speed", type=float, default=10.0, metavar="MM_S", help="travel speed, mm/s (default 10)")
    p.add_argument("--rate", type=float, default=25.0, metavar="HZ", help="control rate, Hz (default 25)")
    p.add_argument("--length", type=float, default=None, metavar="MM",
                   help="weld this length then stop (default: to the end of the seam)")
    p.add_argument("--seed", metavar="U,V", help="a pixel inside the groove in the left view of the first "
                                                 "sensor frame (default: found on the middle row)")
    p.add_argument("--true-rig", metavar="RIG", help="the rig as built, through which the world is rendered "
                                                     "(name or file; default: --rig). The sensor uses only --rig, "
                                                     "e.g. what psvs calibrate found, as on real glass")
    p.add_argument("--handeye", metavar="HANDEYE.toml", help="the hand-eye transform from psvs handeye (default: "
                                                             "calibrate it in the cell first, ~12 s)")
    p.add_argument("--roi-rows", type=int, default=None,
                   help="sensor window rows (default: the rows 32 rows of the paper's camera span, the same "
                        "length of seam: 32 on the paper's camera, 66 on mv1440)")
    p.add_argument("--no-bag", action="store_true", help="do not write the ROS 2 bag")
    p.add_argument("--bag-storage", choices=("mcap", "sqlite3"), default="mcap",
                   help="the ROS 2 bag's storage (default mcap, rosbag2's default)")
    add_telemetry_arguments(p)
    add_check_arguments(p)
    p.add_argument("--stop-on-drift", action="store_true",
                   help="stop safely (brake, arc off) when the self-check finds the calibration has drifted")
    p.add_argument("-o", "--output", metavar="RUN_DIR", required=True, help="folder for the run's outputs")
    p.set_defaults(run=run)


class _Progress:
    """Says when the first control cycle is done (what bench/bench_track.py times from the command's start)
    and passes the run on to the recorder, if any."""

    def __init__(self, recorder):
        self.recorder, self.cycles = recorder, 0

    def started(self, cam2flange, teach) -> None:
        if self.recorder is not None:
            self.recorder.started(cam2flange, teach)

    def cycle(self, c) -> None:
        if self.cycles == 0:
            print("tracking: first control cycle done", flush=True)
        if c.health is not None and c.health.line:
            print(f"psvs track: {c.health.line}", flush=True)
        self.cycles += 1
        if self.recorder is not None:
            self.recorder.cycle(c)


def _job(args):
    """The tracking job, the rigs and the workpiece the arguments ask for, checked before any work."""
    from psvs.io.params import load_rig
    from psvs.robot.controller import TrackConfig
    from psvs.robot.workpiece import seam_workpiece
    for name, v in (("--speed", args.speed), ("--rate", args.rate)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a number > 0, got {v!r}")
    check_tolerance(args)
    if args.stop_on_drift and args.no_check:
        raise ValueError("--stop-on-drift needs the self-check: leave out --no-check")
    rig = measuring_rig(args.rig)
    if args.roi_rows is None:     # the same angle (length of seam) as 32 rows of the paper's camera
        from psvs.robot.budget import default_roi_rows
        args.roi_rows = default_roi_rows(rig)
    cfg = TrackConfig(speed_mm_s=args.speed, rate_hz=args.rate, weld_length_mm=args.length, roi_rows=args.roi_rows)
    true_rig = load_rig(args.true_rig) if args.true_rig else None
    if true_rig is not None and true_rig.camera.image_size_px != rig.camera.image_size_px:
        raise ValueError(f"--true-rig's camera is {true_rig.camera.image_size_px} px but --rig's is "
                         f"{rig.camera.image_size_px} px: one camera")
    if args.roi_rows > rig.camera.image_size_px[1]:
        raise ValueError(f"--roi-rows must be at most the camera's {rig.camera.image_size_px[1]} rows, "
                         f"got {args.roi_rows}")
    wp = seam_workpiece(args.scene, cfg.camera_distance_mm)
    q = wp.seam_local(np.linspace(*wp.x_range_mm, 2001))     # the seam's own length, along its curve
    weldable = float(np.sum(np.linalg.norm(np.diff(q, axis=0), axis=1))) - cfg.arc_on_mm
    if args.length is not None and args.length > weldable:
        raise ValueError(f"--length {args.length:g} mm is longer than the seam's {weldable:g} mm from where the arc "
                         f"is struck ({cfg.arc_on_mm:g} mm in) to its end: leave it out to weld to the end")
    _check_work(args, cfg, true_rig or rig, wp.params["length_mm"])
    return cfg, rig, true_rig, wp


def _check_work(args, cfg, rig, seam_mm: float) -> None:
    """The run's renders and cycles within the time and memory limits, before the hand-eye session: the
    session's views (unless --handeye), then every control cycle of welding --length (or the whole seam)
    (psvs.robot.budget)."""
    from psvs._budget import check_time
    from psvs.robot.budget import check_session_work, track_work
    setup_s = 0.0 if args.handeye else check_session_work(rig, "--handeye FILE (psvs handeye) skips them")
    share = None if args.no_check else args.check_share / 100
    seconds, cycles, frames = track_work(rig, cfg, seam_mm, args.length, share)
    checked = f" and {frames} (--no-check leaves them out)" if frames else ""
    check_time(setup_s + seconds, f"--length/--speed/--rate: {cycles}{checked},",
               "a higher --speed, a lower --rate or a shorter --length")


#: What a run writes into its output folder (besides the bag/ folder).
REPORT_FILES = ("report.json", "log.csv", "top_view.png", "error.png")


def run(args) -> int:
    from psvs.robot.bag import write_bag
    from psvs.robot.loop import Watching, drift_watch, track
    from psvs.robot.report import write_report

    out = check_output_folder(args.output, "output")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {out.parent}")
    check_telemetry_arguments(args)
    outputs = {"--mcap": args.mcap, "--rerun": args.rerun, **{f"-o {out}/{name}": out / name for name in REPORT_FILES}}
    check_distinct(outputs, {"--rig": args.rig, "--true-rig": args.true_rig, "--handeye": args.handeye})
    seed = parse_seed(args.seed)
    cfg, rig, true_rig, wp = _job(args)
    handeye = None
    if args.handeye:
        from psvs.io.params import rig_digest
        from psvs.robot.handeye import check_mount_pinned
        from psvs.robot.handeye_io import check_same_rig, load_handeye
        from psvs.robot.handeye_session import true_cam2flange
        he = load_handeye(args.handeye)
        check_same_rig(he, rig_digest(rig), f"--handeye {args.handeye}", f"--rig {args.rig or 'default'}")
        if he.mount_sigma_mm is not None:   # a file written before the hand-eye fit refused a mount this loose
            check_mount_pinned(he.mount_sigma_mm, he.mount_sigma_rad, f"in {args.handeye}")
        handeye = (he, true_cam2flange(cfg))   # the simulated hardware's truth: scoring
    _check_run_folder(out, (args.mcap, args.rerun))
    made = not out.exists()
    out.mkdir(exist_ok=True)                     # before the run: a recording may go into it
    t0_ns = time.time_ns()                       # the run's start: the recording's and the bag's time base
    try:
        with open_telemetry(args, t0_ns, robot=True) as tel:
            from psvs.robot.recording import RunRecorder, publish_stop
            recorder = None if tel is None else RunRecorder(tel, cfg, seed, rig)
            watch = None if args.no_check else drift_watch(rig, cfg, args.tolerance_px, args.stop_on_drift,
                                                              args.check_share / 100)
            listener = _Progress(recorder) if watch is None else Watching(watch, _Progress(recorder))
            result = track(wp, rig, cfg, seed_px=seed, true_rig=true_rig, handeye=handeye, listener=listener)
            if tel is not None:
                publish_stop(tel, result.cycles[-1].t_s, result.stop.reason)
        summary = write_report(result, wp, out)
        if not args.no_bag:
            write_bag(result, out / "bag", args.bag_storage, t0_ns)
        elif (out / "bag").is_dir():             # an earlier run's bag is not this run's (trial 44)
            shutil.rmtree(out / "bag")
    except BaseException:
        if made and not any(out.iterdir()):      # refused or stopped before writing: no empty folder left
            out.rmdir()
        raise
    _print_summary(summary, bool(args.handeye))
    if not summary["valid_frames"]:
        where = "" if seed is None else f" near the seed ({seed[0]:g}, {seed[1]:g})"
        print(f"psvs track: cannot measure: the seam was never seen: no groove edge{where} in any sensor frame "
              "(the seed off the groove, or the workpiece out of the window?)", file=sys.stderr)
        return 1
    return _exit_status(result.stop.reason)


def _check_run_folder(out, recordings) -> None:
    """ValueError when the output folder (besides this run's own ``recordings``) holds anything but an earlier
    run's files (its :data:`REPORT_FILES` with its report.json, bag/): a run replaces an earlier run's files,
    never a user's (trial 44: a log.csv of the user's own, in the folder given to -o, was replaced without a
    word)."""
    if not out.is_dir():
        return
    ours = {Path(r).name for r in recordings if r and Path(r).parent.resolve() == out.resolve()}
    held = {p.name for p in out.iterdir()} - ours
    foreign = sorted(held - {*REPORT_FILES, "bag"} if "report.json" in held else held)    # no report: no run's
    if foreign:
        more = f" and {len(foreign) - 3} more" if len(foreign) > 3 else ""
        raise ValueError(f"output folder {out} holds what no track run writes ({', '.join(foreign[:3])}{more}): "
                         "give a new folder, or an earlier run's")


#: Stops that are no clean weld besides the drift stop: a fault of the arm (a joint at its limit, an inverse
#: kinematics jump) and a run that never ended by itself. The seam's end, a gap and the weld's length are.
FAULT_STOPS = ("arm: ", "cycle limit reached")


def _exit_status(reason: str) -> int:
    """0 for a run that ended as a weld ends (its length, the seam's end or a gap it cannot bridge, said in
    the summary); 1, with one line, for a stop that is no clean weld: the calibration drifted (said where it
    was found), an arm fault or a run that never ended (an adversarial trial: an inverse kinematics jump
    that welded 0.0 mm exited 0)."""
    from psvs.robot.drift import DRIFT_STOP
    if reason.startswith(DRIFT_STOP):
        return 1                                     # not a clean weld: the glass moved
    if reason.startswith(FAULT_STOPS):
        print(f"psvs track: not a clean weld: the run stopped on {reason}", file=sys.stderr)
        return 1
    return 0


def _print_summary(s: dict, handeye_file: bool) -> None:
    lat, ver, wall = s["lateral_mm"], s["vertical_mm"], s["wall_ms"]
    print(f"set-up before the first control cycle: {s['start_s']:.1f} s" + ("" if handeye_file else
          " (the hand-eye calibration included; --handeye FILE skips it)"))
    print(f"{s['cycles']} cycles ({s['simulated_s']:.1f} s simulated), welded {s['welded_mm']:.1f} mm")
    if lat["rms"] is not None:
        print(f"torch deviation: lateral RMS {lat['rms']:.3f} mm (max {lat['max']:.3f}), "
              f"vertical RMS {ver['rms']:.3f} mm (max {ver['max']:.3f})")
    print(f"wall time per cycle (median): sensor {wall['sensor']['median']:.1f} ms, "
          f"control {wall['control']['median']:.1f} ms, rendering {wall['render (simulation)']['median']:.0f} ms")
    h = s["health"]
    if h is not None:
        figure = "" if h["row_offset_rms_px"] is None else \
            f", twins' rows {h['row_offset_rms_px']:.2f} +- {h['uncertainty_px']:.2f} px RMS"
        late = f"{h['late_steps']} of them longer than" if h["late_steps"] else "all within"
        idle = f" ({h['idle_steps']} in the run-in, {late} its cycle's idle time)" if h["idle_steps"] else ""
        before = "" if h["before_arc"] is None else f"; before the arc: {h['before_arc']['verdict']}"
        print(f"self-check: {h['verdict'] or 'no step taken'}{figure} ({h['steps']} steps{idle}, "
              f"{h['cost_pct']:.1f} % of the sensor's time{before})")
    print(f"stop: {s['stop']['reason']} (torch at s = {s['stop']['torch_s_mm']:.1f} mm)")
