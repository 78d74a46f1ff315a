"""The frame-source options ``psvs live``, ``capture`` and ``serve`` share: ``--video`` or ``--camera`` (an
OpenCV index or ``basler:SERIAL``) and a machine-vision camera's acquisition settings, from the command line
or the rig file's ``[camera.acquisition]`` table (docs/cameras.md)."""
from __future__ import annotations

from psvs.live.camera import TRIGGERS, Acquisition, parse_camera, parse_features

CAMERA_HELP = ("camera: an OpenCV index (0, 1, ...) or a Basler camera, basler:SERIAL or basler:0 (the first "
               "found; needs psvs[basler]); psvs cameras lists them")


def add_source_arguments(parser, required: bool = True) -> None:
    """--video F | --camera SPEC (mutually exclusive) and the acquisition options."""
    src = parser.add_mutually_exclusive_group(required=required)
    src.add_argument("--video", metavar="F", help="video file, printf-style image sequence (seq_%%03d.png) or "
                                                  "folder of images")
    src.add_argument("--camera", metavar="N|basler:SERIAL", help=CAMERA_HELP)
    add_acquisition_arguments(parser)


def add_acquisition_arguments(parser) -> None:
    """A machine-vision camera's acquisition options (exposure, gain, rate, format, trigger, features)."""
    g = parser.add_argument_group("camera acquisition (a machine-vision camera; the rig file's "
                                  "[camera.acquisition] table gives defaults)")
    g.add_argument("--exposure-us", type=float, metavar="US", help="exposure time, microseconds")
    g.add_argument("--gain-db", type=float, metavar="DB", help="gain, dB")
    g.add_argument("--frame-rate", type=float, metavar="HZ", help="acquisition frame rate, Hz (free run)")
    g.add_argument("--pixel-format", metavar="FMT", help="Mono8, Mono10, Mono12 or a packed variant the camera "
                                                         "has (Mono10p, Mono12p, Mono12Packed)")
    g.add_argument("--trigger", choices=TRIGGERS, help="software: one frame per grab; line1: a hardware trigger "
                                                      "on input line 1 (default: free run)")
    g.add_argument("--auto-exposure", action="store_true", help="let the camera set its exposure (default off: a "
                                                                "measurement needs a fixed response)")
    g.add_argument("--auto-gain", action="store_true", help="let the camera set its gain (default off)")
    g.add_argument("--camera-settings", metavar="FILE.pfs", help="a feature file as pylon Viewer saves it, loaded "
                                                                 "before the options above")
    g.add_argument("--camera-set", metavar="NAME=VALUE", action="append", default=[],
                   help="set any camera feature (repeatable, applied in order, last)")


def acquisition_from_args(args) -> Acquisition:
    """The rig file's ``[camera.acquisition]`` table (when --rig is a file that has one) overridden by the
    command line's options."""
    from pathlib import Path

    from psvs.io.acquisition import load_acquisition
    base = Acquisition()
    rig = getattr(args, "rig", None)
    if rig:
        from psvs.io.params import rig_path
        path = rig_path(rig)
        if Path(path).suffix.lower() == ".toml":
            base = Acquisition(**load_acquisition(path))
    settings = getattr(args, "camera_settings", None)
    if settings is not None and not Path(settings).is_file():
        raise FileNotFoundError(f"--camera-settings: file not found: {settings}")
    cli = Acquisition(exposure_us=getattr(args, "exposure_us", None), gain_db=getattr(args, "gain_db", None),
                      frame_rate_hz=getattr(args, "frame_rate", None), pixel_format=getattr(args, "pixel_format", None),
                      trigger=getattr(args, "trigger", None), auto_exposure=getattr(args, "auto_exposure", False),
                      auto_gain=getattr(args, "auto_gain", False), settings_file=settings,
                      features=parse_features(getattr(args, "camera_set", []) or []))
    return base.merged(cli)


def check_source_arguments(args):
    """The --camera spec parsed and the acquisition checked, before any output is written: (spec or None,
    acquisition). A video given acquisition settings is refused here."""
    acq = acquisition_from_args(args)
    spec = parse_camera(args.camera) if getattr(args, "camera", None) is not None else None
    if spec is None and acq.asks_anything() and _cli_asks(args):
        raise ValueError("camera acquisition options need --camera (a video's frames were taken already)")
    return spec, acq


def _cli_asks(args) -> bool:
    return any(getattr(args, n, None) not in (None, False, []) for n in
               ("exposure_us", "gain_db", "frame_rate", "pixel_format", "trigger", "auto_exposure", "auto_gain",
                "camera_settings", "camera_set"))


def open_source(args):
    """The frame source the arguments name, opened and configured (closed again on a fault): one-line
    ValueError/OSError (exit 2) before anything is written."""
    from psvs.live.source import open_camera, open_video
    spec, acq = check_source_arguments(args)
    if spec is None:
        return open_video(args.video)
    source = open_camera(spec)
    try:
        source.open()
        source.configure(acq if spec.kind != "opencv" else _opencv_acquisition(args, acq))
    except BaseException:
        source.close()
        raise
    return source


def _opencv_acquisition(args, acq: Acquisition) -> Acquisition:
    """An OpenCV camera takes no settings: the command line's are refused; the rig file's (for the machine-vision
    camera the rig was built with) are not applied."""
    return acq if _cli_asks(args) else Acquisition()
