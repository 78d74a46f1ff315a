"""``psvs refit``: re-fit a drifted calibration's mirrors from ordinary frames, optionally tared on a flat
surface at a known distance; or the screw turns that put the glass back (psvs.calibrate.refit,
docs/health.md)."""
from __future__ import annotations

import json
import math
from pathlib import Path

from psvs.calibrate.tare import MIN_TARE_SIGMA_MM, SCALE_PINNED, TARE_SIGMA_MM, tares_scale_sigma
from psvs.cli.common import (
    add_range_arguments,
    add_rig_argument,
    check_distinct,
    check_output_path,
    measuring_rig,
    range_from_args,
)
from psvs.io.atomic import output_batch, write_atomic
from psvs.io.images import read_grey
from psvs.io.params import rig_template, save_rig

#: The record of a refit is written beside the rig file, named after it.
RECORD_SUFFIX = ".refit.json"


def add_parser(sub) -> None:
    p = sub.add_parser("refit", help="re-fit a drifted calibration's mirrors from ordinary frames (+ a tare)",
                       description="From ordinary frames of any textured scene: the mirror tilts that put the "
                                   "twins back on their rows, the rest of the calibration (the lens, the plate, "
                                   "the baseline, the shifts) held; with --tare, a frame of a flat textured "
                                   "surface facing the rig at --tare-mm along its axis, also the depth the rows "
                                   "cannot see (two tares at two distances: its scale too). Writes the rig file "
                                   "(as psvs calibrate does) and a record of the refit beside it (NEW.refit.json: "
                                   "each change with its 1 sigma, what no frame could pin). Exit 1 when the frames "
                                   "cannot give a right answer. docs/health.md.")
    p.add_argument("frames", nargs="+", metavar="FRAME", help="complex images (PNG, JPEG, BMP, TIFF, PNM)")
    add_rig_argument(p)
    p.add_argument("-o", "--output", metavar="NEW.toml",
                   help="refitted rig file (TOML in the --rig file's comments and layout, or .json); its record "
                        f"goes beside it as NEW{RECORD_SUFFIX}")
    p.add_argument("--tare", metavar="IMAGE", action="append", default=[],
                   help="a frame of a flat textured surface facing the rig (give two, at two distances, to pin "
                        "the depth scale as well as its offset)")
    p.add_argument("--tare-mm", type=float, metavar="Z", action="append", default=[],
                   help="each --tare surface's distance along the optical axis from the camera's optical centre, "
                        "mm (in the order of the --tare images)")
    p.add_argument("--tare-sigma-mm", type=float, default=TARE_SIGMA_MM, metavar="S",
                   help="how well each --tare-mm is known, 1 sigma, mm: from the optical centre O as the "
                        f"calibration places it (default {TARE_SIGMA_MM:g}; a robot's accuracy; a tape from the "
                        "rig's front knows O less well); the stated depth sigma includes it")
    p.add_argument("--adjust", action="store_true",
                   help="also print the screw turns that put the twins back on their rows (as psvs adjust)")
    add_range_arguments(p)
    p.add_argument("--tolerance-px", type=float, default=0.5,
                   help="the check's tolerance the refitted rig must meet, px (default 0.5)")
    p.set_defaults(run=run)


def record_path(output: Path) -> Path:
    """Where the record of a refit written to ``output`` goes: NEW.toml -> NEW.refit.json."""
    return output.with_name(output.stem + RECORD_SUFFIX)


def run(args) -> int:
    if args.output is None and not args.adjust:
        raise ValueError("give -o NEW.toml for the refitted rig, or --adjust for the screw turns")
    if len(args.tare) != len(args.tare_mm):
        raise ValueError(f"each tare needs both --tare IMAGE and --tare-mm Z: {len(args.tare)} image(s), "
                         f"{len(args.tare_mm)} distance(s)")
    for z in args.tare_mm:
        if not math.isfinite(z):
            raise ValueError(f"--tare-mm must be a distance in mm, got {z}")
    if not (math.isfinite(args.tare_sigma_mm) and args.tare_sigma_mm >= MIN_TARE_SIGMA_MM):
        raise ValueError(f"--tare-sigma-mm must be a length of at least {MIN_TARE_SIGMA_MM:g} mm (no surface's "
                         f"distance from the optical centre is known exactly), got {args.tare_sigma_mm:g}")
    if not (math.isfinite(args.tolerance_px) and args.tolerance_px > 0):
        raise ValueError(f"--tolerance-px must be a number > 0 px, got {args.tolerance_px}")
    out = check_output_path(args.output, (".toml", ".json"))
    record = None if out is None else check_output_path(str(record_path(out)), (".json",))
    inputs = ({f"frame {k + 1}": f for k, f in enumerate(args.frames)} | {"--rig": args.rig}
              | {f"--tare {k + 1}": f for k, f in enumerate(args.tare)})
    check_distinct({"-o": args.output, "the record": record}, inputs)
    rig = measuring_rig(args.rig)
    near, far = range_from_args(args, rig)
    size = rig.camera.image_size_px
    frames = [read_grey(f, expect_size=size) for f in args.frames]
    tares = [(read_grey(f, expect_size=size), z) for f, z in zip(args.tare, args.tare_mm, strict=True)]
    from psvs.calibrate.refit import refit_rig
    res = refit_rig(frames, rig, tares, near, far, args.tolerance_px, args.tare_sigma_mm)
    for line in summary_lines(res):
        print(line)
    if args.adjust:
        from psvs.mount.guide import alignment_guide, designed_twin
        from psvs.mount.report import guide_or_refusal
        from psvs.mount.seats import seats_for
        print(guide_or_refusal(alignment_guide(res.rig, seats_for(designed_twin(rig)), near, far)))
    if out is not None:
        template = rig_template(args.rig) if out.suffix.lower() != ".json" else None
        with output_batch():          # the rig file and its record land together
            save_rig(res.rig, out, template)
            write_atomic(record, json.dumps(res.as_dict() | {"frames_read": [str(f) for f in args.frames],
                                                             "tare_images": list(args.tare), "rig": str(args.rig)},
                                            indent=2) + "\n")
        print(f"wrote {out} and {record}")
    return 0


def summary_lines(res) -> list[str]:
    """What a refit found, for the terminal: the rows before and after, each change with its 1 sigma, what
    no frame could pin, the tare."""
    b, a = res.before, res.after
    lines = [f"rows before: {b.verdict}, field RMS {b.row_offset_rms_px:.2f} +- {b.uncertainty_px:.2f} px "
             f"({b.tiles} tiles); after the refit: {a.verdict}, {a.row_offset_rms_px:.2f} +- "
             f"{a.uncertainty_px:.2f} px ({a.tiles} tiles)",
             f"refit on {res.pairs} twin pairs of {res.frames} frame(s)"
             + (f" and {res.tare_pairs} of the tare" if res.tare_pairs else "")
             + f": reprojection RMS {res.rms_px:.3f} px; {res.message}",
             f"  {'parameter':<16}{'old':>10}{'new':>10}{'change':>10}  1 sigma"]
    for name, (old, new, s) in res.change.items():
        lines.append(f"  {name:<16}{old:10.4f}{new:10.4f}{new - old:+10.4f}  +- {s:.4f}")
    if res.unpinned:
        from psvs.calibrate.refit import combination_text
        lines.append(f"{len(res.unpinned)} combination(s) of the tilts no frame could pin, held near the old "
                     "calibration by their priors:")
        lines += [f"  {combination_text(c)}" for c in res.unpinned]
    for k, t in enumerate(res.tares):
        lines.append(f"tare {k + 1}: the surface at {t.distance_mm:g} +- {res.tare_sigma_mm:g} mm read "
                     f"{t.before_mm:.2f} mm before, "
                     f"{t.after_mm:.2f} mm after ({t.tiles} tiles, flat to {t.flat_rms_px:.2f} px of disparity, "
                     f"slope {t.slope_deg[0]:+.2f}/{t.slope_deg[1]:+.2f} deg)")
    distances = [t.distance_mm for t in res.tares]
    scale = tares_scale_sigma(distances, res.tare_sigma_mm)
    advice = "" if scale <= SCALE_PINNED else {
        0: "; a tare (--tare IMAGE --tare-mm Z) pins its offset, two at two distances its scale",
        1: "; a second tare at another distance pins its scale"}.get(len(res.tares), "; a tare farther from the "
                                                                      "others pins its scale")
    depth = ", ".join(f"+- {100 * sz:.2f} % at {z:g} mm" for z, sz in res.depth_sigma)
    tared = " and the tares' distances" if res.tares else ""
    lines.append(f"depth on the axis: {depth} (1 sigma) from what no frame pinned{tared}{advice}")
    if res.tares and scale > SCALE_PINNED:
        lines.append(hidden_scale(distances, scale, [z for z, _ in res.depth_sigma]))
    return lines


def hidden_scale(tares_mm, scale_sigma: float, depths_mm) -> str:
    """What tares at ``tares_mm`` that pin a depth scale only to ``scale_sigma`` (relative, 1 sigma;
    :func:`psvs.calibrate.tare.tares_scale_sigma`: inf for one tare) cannot see, in words: a depth scale that the
    held parameters hide (the lens's focal length, the baseline, the mirrors' shifts), which they turn into an
    error of s (Z / Z_tare - 1) at depth Z (depth pinned at their mean distance Z_tare, scaled about it); for
    s = 1 % at ``depths_mm``. (Trial 43: a lens 2 % longer than calibrated, refitted with one tare at 700 mm,
    read walls at 450 and 1150 mm 0.76 % short and 1.4 % long, against 0.71 and 1.29 by this rule, and the
    stated sigma did not say so; two tares at 700 and 720 mm left the same errors and said nothing.)"""
    z_t = sum(tares_mm) / len(tares_mm)
    effect = ", ".join(f"{(z / z_t - 1):+.2f} % at {z:g} mm" for z in depths_mm)
    if len(tares_mm) == 1:
        who, remedy = "one tare", "a second tare at another distance shows it"
    elif math.isinf(scale_sigma):
        who, remedy = f"{len(tares_mm)} tares at one distance", "a tare at another distance shows it"
    else:
        who = (f"{len(tares_mm)} tares {max(tares_mm) - min(tares_mm):g} mm apart (they pin it to "
               f"+- {100 * scale_sigma:.1f} % only)")
        remedy = "a tare farther from the others shows it"
    return (f"held as calibrated: the lens, the plate, the baseline and the mirrors' shifts; a depth scale of 1 % "
            f"they hide from the rows and {who} (a focus ring turned, a mirror slid in its seat) would move "
            f"depth by {effect}, beyond the sigma above: {remedy}")
