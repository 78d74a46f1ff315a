"""``psvs capture``: a capture assistant for calibration views of a hand-held card, on a video or a camera."""
from __future__ import annotations

import sys
import time

from psvs.cli.common import (
    add_rig_argument,
    check_distinct,
    check_output_folder,
    check_working_range,
    rig_from_args,
)


def add_parser(sub) -> None:
    p = sub.add_parser("capture", help="watch a hand-held card, save the views a calibration needs",
                       description="Detect the card (target.toml) in both views of every frame, estimate its pose "
                                   "through the nominal rig, and save each good view once (still, and adding "
                                   "coverage or a new pose) as view_NN.png beside a copy of target.toml in DIR: "
                                   "directly a psvs calibrate folder. Says what is missing (closer, farther, move "
                                   "left, tilt up, hold still; directions as the image shows them) and stops when "
                                   "the set is enough: every cell of the field, near/mid/far, tilts left/right/up/"
                                   "down and flat, and --views views. A video that ends (or Ctrl-C) before that "
                                   "exits 1 saying what is missing, keeping the views saved.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--video", metavar="F", help="video file or printf-style image sequence (OpenCV)")
    src.add_argument("--camera", metavar="N", type=int, help="camera index (OpenCV VideoCapture)")
    p.add_argument("--target", metavar="TARGET.toml", required=True, help="the card (docs/calibration.md)")
    add_rig_argument(p)
    p.add_argument("-o", "--output", metavar="DIR", required=True, help="folder for the views (created; must "
                                                                        "not hold images or target.toml yet)")
    p.add_argument("--views", type=int, default=20, help="views to save at least (3-200, default 20)")
    p.add_argument("--near-mm", type=float, default=400.0, help="near end of the depths to cover, mm (default 400)")
    p.add_argument("--far-mm", type=float, default=900.0, help="far end of the depths to cover, mm (default 900)")
    p.add_argument("--max-speed-px-s", type=float, default=30.0,
                   help="a card whose discs move faster (px/s, between frames) is not saved: hold still "
                        "(default 30: 1 px a frame at 30 frames/s)")
    p.set_defaults(run=run)


def _setup(args):
    """Everything checked before a frame is read: (assistant, folder writer, rig)."""
    from pathlib import Path

    from psvs.calibrate.capture import CaptureAssistant, CaptureFolder, CaptureParams, check_card_visible
    from psvs.calibrate.target_file import load_target
    near, far = check_working_range(args.near_mm, args.far_mm)
    try:
        params = CaptureParams(views=args.views, near_mm=near, far_mm=far, max_speed_px_s=args.max_speed_px_s)
    except ValueError as exc:
        raise ValueError(f"--{str(exc).replace('max_speed_px_s', 'max-speed-px-s')}") from None
    out = check_output_folder(args.output)
    check_distinct({"-o (its target.toml)": out / "target.toml"},
                   {"--target": args.target, "--rig": args.rig, "--video": args.video})
    rig = rig_from_args(args)
    target = load_target(args.target)
    check_card_visible(rig, target, params)
    folder = CaptureFolder(out, Path(args.target).read_bytes())
    return CaptureAssistant(target, rig, params), folder, rig


def run(args) -> int:
    from psvs.calibrate.capture import event_lines
    from psvs.errors import MeasurementError
    from psvs.live.source import VideoSource
    assistant, folder, rig = _setup(args)
    w, h = rig.camera.image_size_px
    source = VideoSource(video=args.video) if args.video else VideoSource(camera=args.camera)
    with source:
        period = 1.0 / source.fps if args.video and source.fps > 0 else (1 / 30 if args.video else None)
        t0 = time.monotonic()
        print(f"psvs capture: watching {source.name}; show the card ({assistant.params.views} views, "
              f"{assistant.params.near_mm:g}-{assistant.params.far_mm:g} mm)", flush=True)
        try:
            for k, frame in enumerate(source):
                if frame.shape != (h, w):
                    raise ValueError(f"{source.name}'s frames are {frame.shape[1]}x{frame.shape[0]} px but the "
                                     f"rig's camera is {w}x{h} px")
                step = assistant.step(frame, k * period if period else time.monotonic() - t0)
                name = folder.save(frame) if step.status == "saved" else None
                for line in event_lines(step, name, assistant.params.views):
                    print(line, flush=True)
                if step.complete:
                    print(f"enough to calibrate: {step.saved} views in {folder.folder} "
                          f"(psvs calibrate {folder.folder} --rig ... -o RIG.toml)", flush=True)
                    return 0
        except KeyboardInterrupt:
            pass
    try:
        assistant.require_enough()
    except MeasurementError as exc:
        kept = f" (kept {len(folder.names)} in {folder.folder})" if folder.names else ""
        print(f"psvs capture: {exc}{kept}", file=sys.stderr)
        return 1
    return 0
