"""``psvs live``: headless real-time sensing: track one edge through a video or a camera, print its depth."""
from __future__ import annotations

import sys
import time
from dataclasses import replace

import numpy as np

from psvs._budget import check_memory
from psvs.cli.camera_args import add_source_arguments, check_source_arguments, open_source
from psvs.cli.common import (
    add_check_arguments,
    add_model_argument,
    add_pipeline_argument,
    add_range_arguments,
    add_rig_argument,
    add_telemetry_arguments,
    check_distinct,
    check_output_path,
    check_telemetry_arguments,
    check_tolerance,
    measuring_model,
    measuring_rig,
    open_telemetry,
    parse_seed,
    pipeline_from_args,
    range_from_args,
    rig_from_args,
)
from psvs.cli.recording import record_settings, settings_paths
from psvs.dense.compiled import announce_dense
from psvs.dense.params import DEFAULT, FAST
from psvs.io import DamagedVideo
from psvs.live.camera import CameraLost
from psvs.live.dense import DenseSensor
from psvs.live.drift_gate import drifted, withheld
from psvs.live.log import write_log
from psvs.live.tracker import EdgeTracker
from psvs.match.correspondence import MatchParams


def add_parser(sub) -> None:
    p = sub.add_parser("live", help="track an edge through live video and print its depth every frame",
                       description="The PSVS as a real-time sensor: frames from a video file (or an image sequence "
                                   "such as seq_%03d.png) or a camera; the edge under --seed is matched with the "
                                   "paper's algorithm on the first frame and re-seeded at its new position on "
                                   "every later frame. Prints one line per frame (depth, disparity, latency); "
                                   "Ctrl-C stops a camera and still writes the log.")
    add_source_arguments(p)
    add_rig_argument(p)
    p.add_argument("--seed", metavar="U,V", help="a point on a left-view edge in the first frame (px); required "
                                                 "unless --dense")
    p.add_argument("--dense", action="store_true", help="also a dense depth map of every frame (psvs disparity's "
                                                        "default mode over the working range; docs/dense.md)")
    p.add_argument("--fast", action="store_true", help="with --dense: its fast mode (psvs disparity --fast), the one "
                                                       "for camera rate (docs/benchmarks.md)")
    p.add_argument("--dense-stride", type=int, default=4, metavar="N",
                   help="with --dense: triangulate one map pixel in N along each axis (default 4)")
    p.add_argument("-o", "--output", metavar="LOG.csv", help="per-frame log (CSV)")
    add_pipeline_argument(p)
    add_range_arguments(p)
    add_model_argument(p)
    p.add_argument("--max-frames", type=int, help="stop after N frames")
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    add_telemetry_arguments(p)
    add_check_arguments(p)
    p.add_argument("--realtime", action="store_true", help="play a video at its frame rate (as a camera delivers "
                                                           "it) instead of as fast as possible")
    p.set_defaults(run=run)


#: The least points along each side of the map a --dense-stride must leave.
MIN_STRIDE_POINTS = 8


def _sensors(args):
    """The edge tracker and the dense sensor the arguments ask for (None each when not asked), checked
    before any frame is read."""
    from psvs.health.check import frame_checker
    if args.max_frames is not None and args.max_frames < 1:
        raise ValueError(f"--max-frames must be >= 1, got {args.max_frames}")
    if args.seed is None and not args.dense:
        raise ValueError("give --seed U,V (an edge to track) or --dense (a depth map per frame), or both")
    if args.fast and not args.dense:
        raise ValueError("--fast is the dense map's fast mode: give it with --dense")
    if args.dense_stride < 1:
        raise ValueError(f"--dense-stride must be >= 1, got {args.dense_stride}")
    seed = parse_seed(args.seed) if args.seed is not None else None
    rig = measuring_rig(args.rig)
    pipeline = pipeline_from_args(args)
    near_mm, far_mm = range_from_args(args, rig)
    measuring_model(args, rig, near_mm, far_mm)
    most = min(rig.camera.image_size_px) // MIN_STRIDE_POINTS
    if args.dense and args.dense_stride > most:     # (trial 44: 700 px left one corner pixel a frame, "100 %")
        raise ValueError(f"--dense-stride must be at most {most} px on this {rig.camera.image_size_px[0]}x"
                         f"{rig.camera.image_size_px[1]} camera (at least {MIN_STRIDE_POINTS} points along each "
                         f"side of the map), got {args.dense_stride}")
    tracker = None if seed is None else EdgeTracker(rig, seed, pipeline=pipeline, near_mm=near_mm, far_mm=far_mm,
                                                    match=MatchParams(model=args.model),
                                                    frame_check=frame_checker(rig, near_mm, far_mm))
    dense = DenseSensor(rig, near_mm, far_mm, params=FAST if args.fast else DEFAULT,
                                   stride=args.dense_stride) if args.dense else None
    return tracker, dense, rolling_check(args, rig, near_mm, far_mm)


def rolling_check(args, rig, near_mm: float, far_mm: float):
    """The rolling self-check (psvs.health.rolling) the arguments ask for (None with --no-check), its
    tolerance checked first."""
    check_tolerance(args)
    if args.no_check:
        return None
    from psvs.health.rolling import RollingCheck
    return RollingCheck(rig, near_mm, far_mm, args.tolerance_px, args.check_share / 100)


def check_step(health, image, frame: int, sensor_s: float, tel, t_s: float, command: str):
    """One frame through the rolling check (when there is one): its one line when the verdict crosses the
    tolerance (printed, and logged on the recording), its /psvs/health record when it judged. Returns its
    latest judgement (None before the first)."""
    if health is None:
        return None
    steps = health.steps
    event = health.step(image, frame, sensor_s)
    if event is not None:
        print(f"psvs {command}: {event.line}", flush=True)
        if tel is not None:
            tel.log(t_s, event.line, "warning" if event.check.verdict == "drifted" else "info")
    if tel is not None and health.steps > steps:
        from psvs.health.rolling import health_record
        tel.record("health", t_s, health_record(health.latest, frame, health.cost_share))
    return health.latest


def _loop(args, source, tel, tracker, dense, health) -> tuple[list, list, list, list, float, bool, object]:
    """Every frame of ``source`` through the sensors and the rolling check (until --max-frames, Ctrl-C,
    SIGTERM, a camera lost or a video's damaged or missing frame), published and printed as it comes:
    (tracker steps, dense frames, the frames' metadata without images, the check's latest judgement per
    frame, wall time s, whether the source failed (lost, damaged), the signal that stopped it or None). A
    signal that lands inside a compiled kernel (the dense map's) comes wrapped in a SystemError: it stops the
    loop the same way (it lost the log and the recording)."""
    from psvs.cli.main import signal_inside
    steps, dense_frames, metas, checks, lost, stopped_by = [], [], [], [], False, None
    t0 = time.perf_counter()
    t_first = None
    rig = (tracker if tracker is not None else dense).rig
    try:
        while (frame := source.grab()) is not None:
            if steps:                   # the first frame's size is the sensors' own check (bad input, exit 2)
                _check_frame_size(frame, rig)
            if t_first is None:
                t_first = frame.timestamp_s
            t_s = frame.timestamp_s - t_first       # a video's frames at its own rate; a camera's on its clock
            if args.realtime and frame.clock == "file":
                time.sleep(max(0.0, t0 + t_s - time.perf_counter()))
            t_sensor = time.perf_counter()
            step = tracker.step(frame.image) if tracker is not None else None
            dstep = dense.step(frame.image) if dense is not None else None
            t_sensor = time.perf_counter() - t_sensor
            checks.append(check_step(health, frame.image, len(steps), t_sensor, tel, t_s, "live"))
            if drifted(checks[-1]):     # no depth through a calibration its own frames say has moved
                step, dstep = withheld(step, dstep)
            steps.append(step)
            dense_frames.append(dstep.brief() if dstep is not None else None)   # the log keeps no maps
            metas.append(replace(frame, image=None))
            if tel is not None:
                _publish_frame(tel, t_s, frame, step, dstep, args.dense_stride, dense)
            if not args.quiet:
                print(_frame_line(len(steps) - 1, step, dstep) + _dropped_note(frame), flush=True)
            if args.max_frames is not None and len(steps) >= args.max_frames:
                break
    except KeyboardInterrupt as exc:
        stopped_by = exc
    except (CameraLost, DamagedVideo) as exc:   # stop cleanly: what was grabbed is kept, logged and summarised
        if not metas and isinstance(exc, DamagedVideo):
            raise                                 # (bad input: nothing to keep)
        last = metas[-1] if metas else None
        if isinstance(exc, DamagedVideo):
            what, where = "", f"frames 0-{last.index} are kept"
        else:
            what = "camera lost: "
            where = (f"the last frame was {last.index} (camera frame {last.counter})" if last is not None
                     else "no frame was delivered")
        print(f"psvs live: {what}{exc}; {where}", file=sys.stderr, flush=True)
        lost = True
        if tel is not None:
            tel.log(time.perf_counter() - t0, f"{what}{exc}; {where}", "error")
    except Exception as exc:
        stopped_by = signal_inside(exc)
        if stopped_by is None:
            raise
    return steps, dense_frames, metas, checks, time.perf_counter() - t0, lost, stopped_by


def _check_frame_size(frame, rig) -> None:
    """DamagedVideo (a source whose frame the run cannot use: it stops there and keeps the frames before it)
    when ``frame`` is not the size of the rig's camera (a sequence with another camera's image in it)."""
    w, h = rig.camera.image_size_px
    if frame.image.shape[:2] != (h, w):
        raise DamagedVideo(f"frame {frame.index} is {frame.image.shape[1]}x{frame.image.shape[0]} px but the rig's "
                           f"camera is {w}x{h} px")


def _dropped_note(frame) -> str:
    return f" ({frame.dropped} frame{'s' * (frame.dropped > 1)} dropped before it)" if frame.dropped else ""


def _publish_frame(tel, t_s: float, frame, step, dstep, stride: int, sensor=None) -> None:
    """A frame's image, its /psvs/frame record {frame, camera_frame, timestamp_s, clock, dropped} and what the
    sensors found in it."""
    tel.image(t_s, frame.image)
    tel.record("frame", t_s, {"frame": frame.index, "camera_frame": frame.counter,
                              "timestamp_s": frame.timestamp_s, "clock": frame.clock, "dropped": frame.dropped})
    if step is not None:
        publish_step(tel, t_s, step)
    if dstep is not None:
        publish_dense(tel, t_s, dstep, stride, sensor)


#: What a run keeps of each frame for its log and summary, bytes: the tracked edge's pair (up to ~500 pixel
#: pairs with their points) and the dense frame's numbers, rounded up.
KEPT_BYTES_PER_FRAME = 32 * 1024


def _check_frames(args, source) -> None:
    """ValueError, before any frame is read, when the frames the run would keep (--max-frames, or a video's
    own count when smaller) do not fit in memory. A camera without --max-frames runs until Ctrl-C."""
    counts = [n for n in (args.max_frames, source.frame_count) if n is not None and n > 0]
    if counts:
        n = min(counts)
        what = f"--max-frames {args.max_frames}" if n == args.max_frames else f"{source.name}'s {n} frames"
        check_memory(n * KEPT_BYTES_PER_FRAME, f"{what} ({KEPT_BYTES_PER_FRAME // 1024} KiB kept a frame for "
                     "the log)", "fewer --max-frames")


def run(args) -> int:
    out = check_output_path(args.output, (".csv",))
    check_telemetry_arguments(args)
    check_distinct({"-o": args.output, "--mcap": args.mcap, "--rerun": args.rerun, **settings_paths(args, out)},
                   {"--video": args.video, "--rig": args.rig, "--pipeline": args.pipeline,
                    "--camera-settings": args.camera_settings})
    check_source_arguments(args)
    tracker, dense, health = _sensors(args)
    source = open_source(args)
    with source:
        _check_frames(args, source)
        if dense is not None:
            announce_dense("psvs live")
        with open_telemetry(args) as tel:
            if hasattr(tel, "rig"):     # Rerun: the rig in 3-D, the image in its camera's field
                tel.rig(rig_from_args(args), *range_from_args(args))
            steps, dense_frames, metas, checks, wall, lost, stopped_by = _loop(args, source, tel, tracker, dense,
                                                                               health)
            if not steps:               # inside: a recording of nothing is discarded, not kept
                raise ValueError(f"no frame could be read from {source.name}")
        record_settings(args, out, source)
    if out:
        write_log(out, steps, dense_frames if dense is not None else None, metas,
                  checks if health is not None else None)
    dropped = sum(m.dropped for m in metas)
    if args.camera is not None or dropped:
        print(f"{source.name}: {dropped} frame{'s' * (dropped != 1)} dropped (frame counters {metas[0].counter}-"
              f"{metas[-1].counter}), timestamps on the {metas[-1].clock} clock")
    if health is not None:
        print(health_summary(health))
    status = _summary(steps, dense_frames if dense is not None else None, wall, args.realtime,
                      "fast" if args.fast else "default")
    if health is not None and status == 0 and any(drifted(c) for c in checks):
        first = next(k for k, c in enumerate(checks) if drifted(c))
        print(f"psvs live: cannot measure from frame {first} on: the calibration has drifted "
              f"({checks[first].reason}): no depth given from there (psvs check, psvs refit)", file=sys.stderr)
        status = 1
    from psvs.cli.main import Terminated
    if isinstance(stopped_by, Terminated):   # the outputs written: then the shell's status for the signal
        raise stopped_by
    return max(status, 1) if lost else status


def health_summary(health) -> str:
    """The rolling check's last word on a run: its verdict and figures, and what it cost."""
    cost = f"{health.steps} steps, {100 * health.cost_share:.1f} % of the sensor's time"
    c = health.latest
    if c is None:
        return f"self-check: no step yet ({cost}): the run was too short for it"
    return f"self-check: {c.verdict}: {c.reason} ({cost})"


def _summary(steps: list, dense_frames: list | None, wall: float, realtime: bool, mode: str) -> int:
    """Print the run's summary (``mode``: the dense map's, default or fast); exit status 1 when nothing was
    measured."""
    n = len(steps)
    pace = "paced by --realtime" if realtime else "reading + processing"
    z = np.zeros(0)
    if dense_frames is not None:
        z = np.array([d.median_z_mm for d in dense_frames])
        z = z[np.isfinite(z)]
        print(f"dense ({mode} mode): {n} frames, {len(z)} with depth, median Z "
              + (f"{np.median(z):.1f} mm" if len(z) else "none")
              + f", {np.mean([d.answered_pct for d in dense_frames]):.1f} % of pixels answered, "
              f"mean {1e3 * np.mean([d.elapsed_s for d in dense_frames]):.1f} ms per frame")
    if steps[0] is None:
        print(f"{n} frames, {n / wall:.1f} frames/s ({pace})")
        if not len(z):
            refusals = [d.refusal for d in dense_frames if d.tested and d.refusal]
            unsupported = any(d.mapped for d in dense_frames) and not any(d.supported for d in dense_frames)
            why = ("no frame's echo stands above chance (psvs disparity's test): no depth" if unsupported else
                   "no frame gave a dense depth (no texture in the working range?)")
            print("psvs live: cannot measure: " + (refusals[-1] if refusals else why), file=sys.stderr)
            return 1
        return 0
    tracked = sum(s.ok for s in steps)
    print(f"{n} frames, {tracked} tracked, {n / wall:.1f} frames/s "
          f"({pace}), mean latency {1e3 * sum(s.elapsed_s for s in steps) / n:.1f} ms")
    if tracked == 0:
        print(f"psvs live: cannot measure: the edge was never found: {steps[0].message}", file=sys.stderr)
        return 1
    return 0


def _frame_line(k: int, step, dstep) -> str:
    parts = []
    if step is not None:
        parts.append(f"Z {step.depth_mm:.2f} mm, disparity {step.disparity_px:.2f} px, {len(step.pair)} pairs, "
                     f"{step.elapsed_s * 1e3:.1f} ms" if step.ok else step.message)
    if dstep is not None:
        parts.append(f"dense median Z {dstep.median_z_mm:.1f} mm, {dstep.answered_pct:.0f} % answered, "
                     f"{dstep.elapsed_s * 1e3:.1f} ms" if dstep.supported else
                     f"dense: no depth, {dstep.refusal or 'the echo does not stand above chance'}, "
                     f"{dstep.elapsed_s * 1e3:.1f} ms")
    return f"frame {k}: " + "; ".join(parts)


def publish_step(tel, t_s: float, step) -> None:
    """The tracked edge of one frame on the Foxglove channels (psvs.io.telemetry): the pair's edge pixels,
    its points (frame C), and a /psvs/depth record {frame, tracked, depth_mm, disparity_px, message}."""
    if step.pair is not None:
        tel.edges(t_s, step.pair.left_px, step.pair.right_px)
        tel.points(t_s, step.pair.points_mm)
    else:
        tel.log(t_s, f"frame {step.frame}: {step.message}", "warning")
    tel.record("depth", t_s, {"frame": step.frame, "tracked": step.ok, "depth_mm": step.depth_mm,
                              "disparity_px": step.disparity_px, "message": step.message})


def publish_dense(tel, t_s: float, d, stride: int, sensor=None) -> None:
    """One frame's dense result: the strided depth image (metres, 32FC1, NaN where none) on
    /psvs/dense/depth, its cloud on /psvs/dense/points, and a /psvs/dense record {frame, median_z_mm,
    answered_pct, elapsed_ms, stride}. A sink that takes maps and views (Rerun) also gets the frame's
    disparity map where its answer holds (NaN elsewhere: not supported) and, on the frames the echo test ran
    on, the separated views of ``sensor`` (the DenseSensor), which cost several fast maps."""
    if hasattr(tel, "disparity"):
        held = d.held if d.held is not None and d.supported else np.zeros(d.disparity_px.shape, bool)
        tel.disparity(t_s, np.where(held, d.disparity_px, np.float32(np.nan)), "dense_disparity")
        if d.tested and sensor is not None and hasattr(tel, "views"):
            tel.views(t_s, *sensor.views())
    tel.depth_image(t_s, d.depth_mm, "/psvs/dense/depth")
    tel.points(t_s, d.points_mm, topic="/psvs/dense/points")
    tel.record("dense", t_s, {"frame": d.frame, "median_z_mm": d.median_z_mm, "answered_pct": d.answered_pct,
                              "elapsed_ms": d.elapsed_s * 1e3, "stride": stride})
