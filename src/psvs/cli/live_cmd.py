"""``psvs live``: headless real-time sensing: track one edge through a video or a camera, print its depth."""
from __future__ import annotations

import sys
import time

from psvs.cli.common import (add_rig_argument, add_telemetry_arguments, check_output_path, check_working_range,
                             open_telemetry, parse_seed, rig_from_args)
from psvs.imaging.pipeline import PAPER, load_pipeline
from psvs.live.log import write_log
from psvs.live.source import VideoSource
from psvs.live.tracker import EdgeTracker
from psvs.measure.triangulate import MODELS


def add_parser(sub) -> None:
    p = sub.add_parser("live", help="track an edge through live video and print its depth every frame",
                       description="The PSVS as a real-time sensor: frames from a video file (or an image sequence "
                                   "such as seq_%03d.png) or a camera; the edge under --seed is matched with the "
                                   "paper's algorithm on the first frame and re-seeded at its new position on "
                                   "every later frame. Prints one line per frame (depth, disparity, latency); "
                                   "Ctrl-C stops a camera and still writes the log.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--video", metavar="F", help="video file or printf-style image sequence (OpenCV)")
    src.add_argument("--camera", metavar="N", type=int, help="camera index (OpenCV VideoCapture)")
    add_rig_argument(p)
    p.add_argument("--seed", metavar="U,V", required=True, help="a point on a left-view edge in the first frame (px)")
    p.add_argument("-o", "--output", metavar="LOG.csv", help="per-frame log (CSV)")
    p.add_argument("--pipeline", metavar="P.toml", help="image pipeline (default: median 3, threshold 92, Roberts)")
    p.add_argument("--near-mm", type=float, default=400.0, help="working range near end (default 400)")
    p.add_argument("--far-mm", type=float, default=1200.0, help="working range far end (default 1200)")
    p.add_argument("--model", choices=MODELS, default=None,
                   help="triangulation model (default: refraction on the paper's geometry, exact on a build)")
    p.add_argument("--max-frames", type=int, help="stop after N frames")
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    add_telemetry_arguments(p)
    p.add_argument("--realtime", action="store_true", help="play a video at its frame rate (as a camera delivers "
                                                           "it) instead of as fast as possible")
    p.set_defaults(run=run)


def run(args) -> int:
    out = check_output_path(args.output, (".csv",))
    if args.max_frames is not None and args.max_frames < 1:
        raise ValueError(f"--max-frames must be >= 1, got {args.max_frames}")
    seed = parse_seed(args.seed)
    rig = rig_from_args(args)
    pipeline = load_pipeline(args.pipeline) if args.pipeline else PAPER
    check_working_range(args.near_mm, args.far_mm)
    tracker = EdgeTracker(rig, seed, pipeline=pipeline, near_mm=args.near_mm, far_mm=args.far_mm, model=args.model)
    steps = []
    with VideoSource(video=args.video, camera=args.camera) as source, open_telemetry(args) as tel:
        period = 1.0 / source.fps if (args.video and source.fps > 0) else None
        t0 = time.perf_counter()
        try:
            for frame in source:
                k, arrived_s = len(steps), time.perf_counter() - t0
                if args.realtime and period is not None:
                    time.sleep(max(0.0, t0 + k * period - time.perf_counter()))
                step = tracker.step(frame)
                steps.append(step)
                if tel is not None:   # a video's frames at its own rate; a camera's at their arrival
                    publish_step(tel, k * period if period is not None else arrived_s, frame, step)
                if not args.quiet:
                    if step.ok:
                        print(f"frame {step.frame}: Z {step.depth_mm:.2f} mm, disparity {step.disparity_px:.2f} px, "
                              f"{len(step.pair)} pairs, {step.elapsed_s * 1e3:.1f} ms", flush=True)
                    else:
                        print(f"frame {step.frame}: {step.message}", flush=True)
                if args.max_frames is not None and len(steps) >= args.max_frames:
                    break
        except KeyboardInterrupt:
            pass
        wall = time.perf_counter() - t0
        if not steps:               # inside: a recording of nothing is discarded, not kept
            raise ValueError(f"no frame could be read from {source.name}")
    if out:
        write_log(out, steps)
    tracked = sum(s.ok for s in steps)
    print(f"{len(steps)} frames, {tracked} tracked, {len(steps) / wall:.1f} frames/s "
          f"({'paced by --realtime' if args.realtime else 'reading + processing'}), mean latency {1e3 * sum(s.elapsed_s for s in steps) / len(steps):.1f} ms")
    if tracked == 0:
        print(f"the edge was never found: {steps[0].message}", file=sys.stderr)
        return 1
    return 0


def publish_step(tel, t_s: float, frame, step) -> None:
    """One frame of ``psvs live`` on the Foxglove channels (psvs.io.telemetry): the frame, the pair's edge
    pixels, its points (frame C), and a /psvs/depth record {frame, tracked, depth_mm, disparity_px, message}."""
    tel.image(t_s, frame)
    if step.pair is not None:
        tel.edges(t_s, step.pair.left_px, step.pair.right_px)
        tel.points(t_s, step.pair.points_mm)
    else:
        tel.log(t_s, f"frame {step.frame}: {step.message}", "warning")
    tel.record("depth", t_s, {"frame": step.frame, "tracked": step.ok, "depth_mm": step.depth_mm,
                              "disparity_px": step.disparity_px, "message": step.message})
