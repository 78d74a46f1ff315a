"""Helpers shared by the subcommands."""
from __future__ import annotations

import argparse
import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from psvs.io import check_writable
from psvs.io.params import load_rig
from psvs.optics.layout_check import check_clear
from psvs.optics.rig import Rig, default_rig
from psvs.rigs import SHIPPED


def add_rig_argument(parser, required: bool = True) -> None:
    parser.add_argument("--rig", metavar="RIG.toml", required=required,
                        help="rig file (TOML or JSON; see docs/rig_file.md), or a shipped rig: "
                             f"{', '.join(SHIPPED)} (psvs rig list)" +
                             ("" if required else "; default: the paper's rig"))


class _RangeGiven(argparse.Action):
    """Stores the value and marks the namespace ``range_given`` (only when given: a command that takes its
    search another way, ``disparity --min-disparity``, can refuse a range it would leave unused)."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        namespace.range_given = True


def add_range_arguments(parser, what: str = "working range") -> None:
    """--near-mm and --far-mm: the depths (mm) of ``what`` (checked by :func:`range_from_args`)."""
    parser.add_argument("--near-mm", type=float, default=400.0, action=_RangeGiven,
                        help=f"near end of the {what}, mm (default 400)")
    parser.add_argument("--far-mm", type=float, default=1200.0, action=_RangeGiven,
                        help=f"far end of the {what}, mm (default 1200)")


def range_from_args(args, rig=None) -> tuple[float, float]:
    """(near, far) mm of --near-mm/--far-mm, checked (:func:`check_working_range`); with ``rig``, also
    that the range starts in front of the rig's mirrors."""
    return check_working_range(args.near_mm, args.far_mm, rig)


def add_model_argument(parser, default: str | None = None) -> None:
    """--model: the triangulation model (default: the rig's own, refraction on the paper's geometry and
    exact on a build, unless ``default`` names one)."""
    from psvs.measure.triangulate import MODELS
    what = "triangulation model: paper, eqs. (12)-(14); refraction, eqs. (15)-(17); exact, traced rays"
    parser.add_argument("--model", choices=MODELS, default=default,
                        help=f"{what} (default {default})" if default else
                        f"{what} (default: refraction on the paper's geometry, exact on a build)")


def add_pipeline_argument(parser) -> None:
    """--pipeline P.toml: the image pipeline (:func:`pipeline_from_args`)."""
    parser.add_argument("--pipeline", metavar="P.toml",
                        help="image pipeline (default: median 3, threshold 92, Roberts)")


def pipeline_from_args(args):
    """The pipeline file of --pipeline, or the paper's pipeline."""
    from psvs.imaging.pipeline import PAPER
    from psvs.io.pipeline_file import load_pipeline
    return load_pipeline(args.pipeline) if args.pipeline else PAPER


def add_telemetry_arguments(parser) -> None:
    """--foxglove [HOST:]PORT and --mcap FILE (psvs.io.telemetry); --rerun FILE and --rerun-serve PORT
    (psvs.io.rerun_sink, the optional rerun-sdk)."""
    parser.add_argument("--foxglove", metavar="[HOST:]PORT",
                        help="serve the run live to Foxglove (WebSocket, loopback unless HOST is given)")
    parser.add_argument("--mcap", metavar="FILE.mcap", help="record the same channels to an MCAP file")
    add_rerun_arguments(parser)


def add_rerun_arguments(parser, serve: bool = True) -> None:
    """--rerun FILE.rrd and (a run that lasts) --rerun-serve PORT (psvs.io.rerun_sink)."""
    parser.add_argument("--rerun", metavar="FILE.rrd",
                        help="record it for Rerun (pip install 'psvs[rerun]'; docs/live.md)")
    if serve:
        parser.add_argument("--rerun-serve", type=int, metavar="PORT",
                            help="show the run in Rerun's web viewer at http://127.0.0.1:PORT (data on PORT+1)")


def add_check_arguments(parser) -> None:
    """--no-check and --tolerance-px: the rolling self-check of a running sensor (psvs.health.rolling)."""
    parser.add_argument("--no-check", action="store_true",
                        help="leave out the rolling self-check (the twins' rows, 8 %% of the sensor's time; "
                             "docs/health.md)")
    parser.add_argument("--tolerance-px", type=float, default=0.5,
                        help="the self-check's tolerance: the twins' field RMS, px (default 0.5)")
    parser.add_argument("--check-share", type=float, default=8.0, metavar="PCT",
                        help="the share of the sensor's time the self-check may take, %% (default 8: a knock is "
                             "said within a few hundred frames; more says it sooner)")


def check_tolerance(args) -> None:
    """--tolerance-px a number > 0 and --check-share in (0, 100], checked before any work."""
    if not (math.isfinite(args.tolerance_px) and args.tolerance_px > 0):
        raise ValueError(f"--tolerance-px must be a number > 0 px, got {args.tolerance_px}")
    if not (math.isfinite(args.check_share) and 0 < args.check_share <= 100):
        raise ValueError(f"--check-share must be a percentage in (0, 100], got {args.check_share}")


def check_telemetry_arguments(args) -> None:
    """--mcap's path and --foxglove's address checked before any work (nothing is opened or bound)."""
    check_output_path(args.mcap, (".mcap",))
    check_rerun_arguments(args)
    if args.foxglove is not None:
        from psvs.io.telemetry import parse_endpoint
        try:
            parse_endpoint(args.foxglove)
        except ValueError as exc:
            raise ValueError(f"--foxglove: {exc}") from None


def check_rerun_arguments(args) -> None:
    """--rerun's path, --rerun-serve's port and the rerun-sdk package, before any work."""
    check_output_path(args.rerun, (".rrd",))
    port = getattr(args, "rerun_serve", None)
    if port is not None and not 1024 <= port <= 65534:
        raise ValueError(f"--rerun-serve must be a port in 1024..65534 (the data on the next one), got {port}")
    if args.rerun is not None or port is not None:
        from psvs.io.rerun_sink import import_rerun
        import_rerun()


@contextmanager
def open_rerun(args, robot: bool = False, keep_on_interrupt: bool = True):
    """The :class:`psvs.io.rerun_sink.RerunSink` --rerun / --rerun-serve ask for (None when neither), closed
    on exit: the file is moved into place unless the command failed (or was interrupted, unless
    ``keep_on_interrupt``: a live run, which Ctrl-C ends)."""
    rrd, port = check_output_path(args.rerun, (".rrd",)), getattr(args, "rerun_serve", None)
    if rrd is None and port is None:
        yield None
        return
    from psvs.io.rerun_sink import RerunSink
    sink = RerunSink(rrd, port, robot, keep_on_interrupt)
    if sink.url is not None:
        print(f"Rerun: {sink.url}", flush=True)
    with sink:
        yield sink


@contextmanager
def open_telemetry(args, t0_ns: int | None = None, robot: bool = False):
    """The sinks the options ask for, as one (None when none): :class:`psvs.io.telemetry.Telemetry` for
    --foxglove/--mcap, :class:`psvs.io.rerun_sink.RerunSink` for --rerun/--rerun-serve (``robot``: a robot
    run's entity tree), closed on exit: the files are moved into place unless the command failed."""
    mcap = check_output_path(args.mcap, (".mcap",))
    with open_rerun(args, robot) as rerun:
        if mcap is None and args.foxglove is None:
            yield rerun
            return
        from psvs.io.rerun_sink import Tee
        from psvs.io.telemetry import Telemetry, parse_endpoint, url_host
        try:
            serve = parse_endpoint(args.foxglove) if args.foxglove is not None else None
        except ValueError as exc:
            raise ValueError(f"--foxglove: {exc}") from None
        tel = Telemetry(mcap, serve, t0_ns)
        if serve is not None:
            print(f"Foxglove: ws://{url_host(serve[0])}:{tel.port} (Open connection > Foxglove WebSocket)",
                  flush=True)
        with tel:
            yield tel if rerun is None else Tee([tel, rerun])


def rig_from_args(args) -> Rig:
    """The ``--rig`` of ``args`` (a file or a shipped rig's name), the paper's rig without one."""
    return load_rig(args.rig) if args.rig else default_rig()


def measuring_rig(path: str | None) -> Rig:
    """The rig a command measures, fits or exports through (a file, a shipped rig's name, the paper's rig when
    None), refused when its layout is blocked (:func:`psvs.optics.layout_check.check_clear`; exit 2): no build
    has it, and no figure through it describes one."""
    rig = load_rig(path) if path else default_rig()
    return check_clear(rig, f"rig {path}" if path else "the paper's rig")


def measuring_model(args, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> str:
    """``args.model`` (None: the rig's default) checked: refused (ValueError, exit 2) when it is a closed form that
    errs on this build over near..far mm beyond a match's noise (:func:`psvs.measure.model_check.check_closed_form`);
    the model's own depth error on the rig (the one asked, or the rig's default) said on stderr when it is more
    than 0.5 % (the paper's model on the paper's geometry: about 1 % short; the refraction model on a 15 mm plate:
    0.5 %; :func:`psvs.measure.model_check.model_error_note`). Returns that note ("" when there is none)."""
    from psvs.measure.model_check import check_closed_form, model_error_note
    check_closed_form(rig, args.model, near_mm, far_mm)
    note = model_error_note(rig, args.model, near_mm, far_mm)
    if note:
        print(note, file=sys.stderr)
    return note


def check_output_path(path: str | None, suffixes: tuple[str, ...]) -> Path | None:
    """Validate an output path before any work: known suffix, existing folder."""
    if path is None:
        return None
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise ValueError(f"output {p} must end in {' or '.join(suffixes)}")
    if not p.parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {p.parent}")
    if p.is_dir():
        raise ValueError(f"output {p} is a folder, not a file")
    if p.exists() and not os.access(p, os.W_OK):
        raise PermissionError(f"cannot write {p}: permission denied")
    check_writable(p.parent, str(p))
    return p


#: The files of an input folder its readers take (a card's or a sweep's views, a hand-eye run's poses), and
#: the image types of its views: an output may not replace one.
FOLDER_INPUTS = ("target.toml", "sweep.csv", "flange_poses.csv")
FOLDER_INPUT_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".pnm")


def check_distinct(outputs: dict, inputs: dict | None = None) -> None:
    """ValueError when two outputs name one file (the second would silently replace the first) or an output
    names one of the inputs (it would be overwritten by what was computed from it). ``outputs`` and
    ``inputs`` map an option's name (as the user typed it, e.g. ``"--rig-out"``) to its path or None; a rig
    given by a shipped name stands for its file."""
    from psvs.io.params import rig_path
    seen: dict[Path, str] = {}
    for option, path in outputs.items():
        if path is None:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise ValueError(f"{seen[key]} and {option} name the same file {path}: give each its own")
        seen[key] = option
    for option, path in (inputs or {}).items():
        if path is None:
            continue
        try:
            key = (rig_path(path) if option.endswith("rig") else Path(path)).resolve()
        except FileNotFoundError:
            continue             # a missing input is reported where it is read
        if key in seen:
            raise ValueError(f"{seen[key]} names the input {option} ({path}): it would be overwritten")
        if key.is_dir():         # a folder of inputs: what its readers take from it is input too
            for out, opt in seen.items():
                if out.parent == key and out.is_file() and (out.name in FOLDER_INPUTS
                                                            or out.suffix.lower() in FOLDER_INPUT_SUFFIXES):
                    raise ValueError(f"{opt} names {out.name} of the input folder {option} ({path}): it would be "
                                     "overwritten by what was computed from it")


#: mm: the farthest depth a working range may reach (10 km: far beyond any PSVS's use; beyond, the optics'
#: squares overflow: --far-mm 1e155 was an internal error, 1e154 printed a 300-digit depth).
MAX_DEPTH_MM = 1e7


def check_working_range(near_mm: float, far_mm: float, rig=None) -> tuple[float, float]:
    """``--near-mm``/``--far-mm`` as finite depths with 0 < near < far <= :data:`MAX_DEPTH_MM` (mm), else a
    one-line ValueError. With ``rig``, near must also lie beyond the front of its mirrors
    (:func:`psvs.optics.mirrors.check_in_front`)."""
    for name, v in (("--near-mm", near_mm), ("--far-mm", far_mm)):
        if not math.isfinite(v) or v <= 0 or v > MAX_DEPTH_MM:
            raise ValueError(f"{name} must be a finite depth in (0, {MAX_DEPTH_MM:g}] mm, got {v}")
    if near_mm >= far_mm:
        raise ValueError(f"--near-mm ({near_mm} mm) must be less than --far-mm ({far_mm} mm)")
    if rig is not None:
        from psvs.optics.mirrors import check_in_front
        check_in_front(rig, near_mm, "--near-mm")
    return near_mm, far_mm


def load_scene_spec(spec: str):
    """A scene from a scene file (TOML) or a built-in spec such as ``fig9:distance_mm=800``."""
    from psvs.io.scene_file import load_scene
    from psvs.simulate.builtin import BUILTINS, builtin_scene
    if spec.endswith(".toml") or Path(spec).exists():
        return load_scene(spec)
    if spec.partition(":")[0] in BUILTINS:
        return builtin_scene(spec)
    raise ValueError(f"scene {spec!r} is neither a scene file nor a built-in ({', '.join(BUILTINS)})")


def parse_seed(text: str | None, whole: bool = False) -> tuple[float, float] | None:
    """``--seed U,V`` as (u, v) px (with ``whole``, a pixel: whole numbers, the edge map's pixel it names; 200.5
    was read as 200 without a word); None stays None; anything else is a one-line ValueError."""
    if text is None:
        return None
    try:
        u, v = (float(c) for c in text.split(","))
    except ValueError:
        raise ValueError(f"--seed must be 'u,v' in px, got {text!r}") from None
    if not (math.isfinite(u) and math.isfinite(v)):
        raise ValueError(f"--seed must be two finite numbers 'u,v' in px, got {text!r}")
    if whole and not (u.is_integer() and v.is_integer()):
        raise ValueError(f"--seed must name a pixel, 'u,v' in whole px (the edge map's pixel), got {text!r}")
    return u, v
