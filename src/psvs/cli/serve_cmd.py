"""``psvs serve``: the browser UI (FastAPI + uvicorn) on a complex image, a video, a camera or a simulated scene."""
from __future__ import annotations

from psvs.cli.camera_args import CAMERA_HELP, add_acquisition_arguments
from psvs.cli.common import add_rig_argument, load_scene_spec, rig_from_args
from psvs.io.images import read_grey


def add_parser(sub) -> None:
    p = sub.add_parser("serve", help="interactive web UI: pipeline, double-click matching, live mode",
                       description="A local web app: the complex image, the image pipeline with live previews, "
                                   "double-click an edge to match it (the paper's algorithm) and read its "
                                   "disparity and depth, pair every edge automatically, export CSV/JSON/PLY, and "
                                   "track the selected edge live. Open the printed address in a browser.")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--image", metavar="F", help="complex image (PNG, grey)")
    src.add_argument("--video", metavar="F", help="video file (live mode plays it in a loop)")
    src.add_argument("--camera", metavar="N|basler:SERIAL", help=CAMERA_HELP)
    src.add_argument("--scene", metavar="S", help="simulated scene: a built-in (e.g. fig5b) or a scene file "
                                                  "(the default is fig5b)")
    add_rig_argument(p, required=False)
    add_acquisition_arguments(p)
    p.add_argument("--true-rig", metavar="RIG", help="with --scene: render through this rig, the build as it "
                                                     "is (name or file), while matching uses --rig")
    p.add_argument("--target", metavar="TARGET.toml", help="the card of the capture panel (docs/calibration.md)")
    p.add_argument("--capture-to", metavar="DIR", help="with --target: the folder the capture panel saves views "
                                                     "to (created; must not hold images or target.toml yet)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0 picks a free one)")
    p.set_defaults(run=run)


def make_source(args, rig):
    from psvs.io.params import load_rig
    from psvs.web import sources
    true_rig = getattr(args, "true_rig", None)
    if true_rig and (args.image or args.video or args.camera is not None):
        raise ValueError("--true-rig renders a simulated scene: use it with --scene (or no source)")
    if true_rig:
        true_rig = load_rig(true_rig)
        if true_rig.camera.image_size_px != rig.camera.image_size_px:
            raise ValueError(f"--true-rig's camera is {true_rig.camera.image_size_px} px but --rig's is "
                             f"{rig.camera.image_size_px} px: one camera")
    from psvs.cli.camera_args import check_source_arguments
    spec, acquisition = check_source_arguments(args)    # acquisition settings without --camera: refused
    if args.image:
        return sources.image_source(args.image, read_grey(args.image, expect_size=rig.camera.image_size_px))
    if args.video:
        return sources.video_source(args.video)
    if spec is not None:
        return sources.camera_source(spec, acquisition)
    spec = args.scene or "fig5b"
    return sources.scene_source(spec, load_scene_spec(spec), true_rig or rig)


def capture_setup(args):
    """The capture panel's card and folder (--target and --capture-to, both or neither), checked now."""
    if (args.target is None) != (args.capture_to is None):
        raise ValueError("--target and --capture-to go together: the card, and the folder for its views")
    if args.target is None:
        return None
    from pathlib import Path

    from psvs.calibrate.capture import check_capture_folder
    from psvs.calibrate.target_file import load_target
    from psvs.cli.common import check_distinct, check_output_folder
    from psvs.web.capture_runner import CaptureSetup
    folder = check_output_folder(args.capture_to, "--capture-to folder")
    check_capture_folder(folder)
    check_distinct({"--capture-to (its target.toml)": folder / "target.toml"}, {"--target": args.target})
    return CaptureSetup(load_target(args.target), Path(args.target).read_bytes(), str(folder))


def run(args) -> int:
    if not 0 <= args.port <= 65535:
        raise ValueError(f"--port must be 0-65535, got {args.port}")
    import uvicorn

    from psvs.web.app import create_app
    rig = rig_from_args(args)
    capture = capture_setup(args)
    app = create_app(make_source(args, rig), rig, args.rig or "default rig", capture)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"psvs serve: warning: listening on {args.host}: anyone who can reach it can use the UI")
    config = uvicorn.Config(app, host=args.host, port=args.port, log_level="warning")
    server = uvicorn.Server(config)

    def announce():
        for s in server.servers:
            for sock in s.sockets:
                host, port = sock.getsockname()[:2]
                print(f"psvs serve: open http://{'[' + host + ']' if ':' in host else host}:{port}/ "
                      f"(Ctrl-C stops)", flush=True)
    _run_announced(server, announce)
    return 0


def _run_announced(server, announce) -> None:
    """Run the uvicorn server, printing the bound address once it listens."""
    import asyncio

    async def main():
        task = asyncio.create_task(server.serve())
        while not server.started and not task.done():
            await asyncio.sleep(0.05)
        if server.started:
            announce()
        await task
    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        pass
