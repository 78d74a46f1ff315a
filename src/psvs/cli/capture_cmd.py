"""``psvs capture``: a capture assistant for calibration views of a hand-held card, on a video or a camera."""
from __future__ import annotations

import sys

from psvs.cli.camera_args import add_source_arguments, check_source_arguments, open_source
from psvs.cli.common import add_rig_argument, check_distinct, check_working_range, rig_from_args
from psvs.io.atomic import check_output_folder


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
    add_source_arguments(p)
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
    from psvs.targets.target_file import load_target
    near, far = check_working_range(args.near_mm, args.far_mm)
    try:
        params = CaptureParams(views=args.views, near_mm=near, far_mm=far, max_speed_px_s=args.max_speed_px_s)
    except ValueError as exc:
        raise ValueError(f"--{str(exc).replace('max_speed_px_s', 'max-speed-px-s')}") from None
    out = check_output_folder(args.output)
    from psvs.cli.recording import settings_paths
    check_distinct({"-o (its target.toml)": out / "target.toml", **settings_paths(args, None, out)},
                   {"--target": args.target, "--rig": args.rig, "--video": args.video,
                    "--camera-settings": args.camera_settings})
    check_source_arguments(args)
    rig = rig_from_args(args)
    target = load_target(args.target)
    check_card_visible(rig, target, params)
    folder = CaptureFolder(out, Path(args.target).read_bytes())
    return CaptureAssistant(target, rig, params), folder, rig


def run(args) -> int:
    from psvs.calibrate.capture import event_lines
    from psvs.cli.recording import record_settings
    from psvs.live.camera import CameraLost
    assistant, folder, rig = _setup(args)
    w, h = rig.camera.image_size_px
    source = open_source(args)
    with source:
        last = None
        try:
            while (frame := source.grab()) is not None:
                if frame.image.shape != (h, w):
                    raise ValueError(f"{source.name}'s frames are {frame.image.shape[1]}x{frame.image.shape[0]} px "
                                     f"but the rig's camera is {w}x{h} px")
                if last is None:     # (after the first frame's size: a wrong source says only that)
                    print(f"psvs capture: watching {source.name}; show the card ({assistant.params.views} views, "
                          f"{assistant.params.near_mm:g}-{assistant.params.far_mm:g} mm)", flush=True)
                last = frame
                # a file without a rate: 30 frames/s, as a camera
                t_s = frame.index / 30 if frame.clock == "host" and args.video else frame.timestamp_s
                step = assistant.step(frame.image, t_s)
                name = folder.save(frame.image) if step.status == "saved" else None
                if name is not None and len(folder.names) == 1:     # the folder is made by its first view
                    record_settings(args, None, source, folder.folder)
                for line in event_lines(step, name, assistant.params.views):
                    print(line, flush=True)
                if step.complete:
                    print(f"enough to calibrate: {step.saved} views in {folder.folder} "
                          f"(psvs calibrate {folder.folder} --rig ... -o RIG.toml)", flush=True)
                    return 0
        except KeyboardInterrupt:
            pass
        except CameraLost as exc:
            where = f"the last frame was {last.index} (camera frame {last.counter})" if last else "no frame came"
            print(f"psvs capture: camera lost: {exc}; {where}", file=sys.stderr, flush=True)
    return _incomplete(assistant, folder)


def _incomplete(assistant, folder) -> int:
    """Exit status 1 saying what is missing (the views saved are kept), or 0 when the set is enough."""
    from psvs.errors import MeasurementError
    try:
        assistant.require_enough()
    except MeasurementError as exc:
        kept = f" (kept {len(folder.names)} in {folder.folder})" if folder.names else ""
        print(f"psvs capture: {exc}{kept}", file=sys.stderr)
        return 1
    return 0
