"""``psvs adjust``: the alignment guide -- which screw of which mirror to turn, which way and how far, so that
a calibrated build's twins land on the same rows (psvs.mount, docs/mount.md)."""
from __future__ import annotations

import json
import math
from fractions import Fraction

from psvs.cli.common import add_range_arguments, add_rig_argument, check_distinct, check_output_path, range_from_args
from psvs.io.atomic import write_atomic
from psvs.io.params import load_rig
from psvs.mount.guide import AlignmentGuide, alignment_guide
from psvs.mount.seats import DEFAULT_PITCH_MM, seats_for
from psvs.optics.rig import Rig

TILTS = {"a": "tilt a (about the vertical)", "b": "tilt b (out of vertical)"}
#: Design values a calibrated build must share with the rig it was calibrated from (the same mirror box):
#: within 5 % (calibration refines the baseline, e.g. 99.1 mm for a 100 mm design) or 1 deg.
DESIGN_FIELDS = ("baseline_mm", "m1_axis_distance_mm", "m2_axis_distance_mm", "angle_rad")
DESIGN_REL_TOL, DESIGN_ANGLE_TOL_RAD = 0.05, math.radians(1.0)


def add_parser(sub) -> None:
    p = sub.add_parser("adjust", help="screw turns that align a calibrated build's mirrors",
                       description="Turn a calibrated build (psvs calibrate's rig file) into screw turns on the "
                                   "mirrors' seats (a pivot and two screws per mirror, placed on the --rig "
                                   "design's mirrors): which mirror, which screw, which way, how many turns (to "
                                   "1/16), so that the twins of every point land on the same rows over the "
                                   "working range; the row offset before and after. docs/mount.md.")
    p.add_argument("calibrated", metavar="CALIBRATED_RIG.toml", help="the calibrated build (psvs calibrate -o)")
    add_rig_argument(p)
    add_range_arguments(p)
    p.add_argument("--pitch-mm", type=float, default=DEFAULT_PITCH_MM,
                   help=f"screw pitch, mm per turn (default {DEFAULT_PITCH_MM}: M3 x 0.5)")
    p.add_argument("--mount", metavar="MOUNT_DIR",
                   help="the seats psvs mount wrote there (mount.toml) instead of the default ones")
    p.add_argument("--json", metavar="FILE.json", help="also write the guide here")
    p.set_defaults(run=run)


def check_same_design(built: Rig, nominal: Rig) -> None:
    """ValueError unless the calibrated build and the design share the mirror box's layout."""
    for name in DESIGN_FIELDS:
        a, b = getattr(built.mirrors, name), getattr(nominal.mirrors, name)
        close = abs(a - b) <= DESIGN_ANGLE_TOL_RAD if name == "angle_rad" else abs(a - b) <= DESIGN_REL_TOL * abs(b)
        if not close:
            unit = "deg" if name.endswith("rad") else "mm"
            conv = math.degrees if unit == "deg" else float
            raise ValueError(f"the calibrated rig and --rig are not one design: {name.replace('_rad', '')} "
                             f"{conv(a):g} vs {conv(b):g} {unit} (give the design the build was calibrated from)")


def turns_text(turns: float) -> str:
    """'1 3/16 turn', '1/4 turn', '0' for a multiple of 1/16 turn (sign dropped)."""
    f = Fraction(abs(turns)).limit_denominator(16)
    whole, rest = divmod(f, 1)
    if f == 0:
        return "0"
    parts = ([str(whole)] if whole else []) + ([f"{rest.numerator}/{rest.denominator}"] if rest else [])
    return " ".join(parts) + (" turns" if f > 1 else " turn")


def format_guide(g: AlignmentGuide) -> str:
    """The guide as a table a builder follows at the bench."""
    lines = [f"alignment guide: {g.n_points} field points over {g.near_mm:g}-{g.far_mm:g} mm, screws of "
             f"{g.pitch_mm:g} mm pitch (clockwise = seen from behind the mirror)",
             f"twins' row offset before: largest {g.before_px[0]:.2f} px, RMS {g.before_px[1]:.2f} px",
             f"{'mirror':6} {'screw':5} {'trims':29} {'deg/turn':>9}  turn"]
    for t in g.turns:
        how = "leave" if t.turns == 0 else f"{turns_text(t.turns)} {t.direction}"
        lines.append(f"{t.mirror.upper():6} {t.screw:5} {TILTS[t.tilt]:29} {math.degrees(t.rad_per_turn):9.3f}  {how}")
    lines.append(f"twins' row offset after the turns (predicted): largest {g.after_px[0]:.2f} px, "
                 f"RMS {g.after_px[1]:.2f} px ({g.after_unquantised_px[0]:.2f} px with turns not rounded to 1/16)")
    if g.null_space:
        lines.append(f"{len(g.null_space)} combination(s) of turns move no twin off its partner's row (< 0.02 px "
                     "per turn: they move both twins alike, or along their rows), so the rows cannot tell them "
                     "apart; the smallest turns were taken, none of:")
        names = [f"{t.mirror.upper()} {t.screw}" for t in g.turns]
        for v in g.null_space:
            big = sorted(range(len(v)), key=lambda k: -abs(v[k]))[:3]
            lines.append("  " + ", ".join(f"{v[k]:+.2f} {names[k]}" for k in big) + " ...")
    return "\n".join(lines)


def guide_to_dict(g: AlignmentGuide) -> dict:
    """The guide as plain data (JSON)."""
    return {
        "near_mm": g.near_mm, "far_mm": g.far_mm, "points": g.n_points, "pitch_mm": g.pitch_mm,
        "row_offset_before_px": {"max": g.before_px[0], "rms": g.before_px[1]},
        "row_offset_after_px": {"max": g.after_px[0], "rms": g.after_px[1]},
        "row_offset_after_unrounded_px": {"max": g.after_unquantised_px[0], "rms": g.after_unquantised_px[1]},
        "turns": [{"mirror": t.mirror.upper(), "screw": t.screw, "tilt": t.tilt, "turns": t.turns,
                   "direction": t.direction, "deg_per_turn": math.degrees(t.rad_per_turn),
                   "shift_mm_per_turn": t.shift_mm_per_turn} for t in g.turns],
        "null_space": [list(v) for v in g.null_space],
        "singular_px_per_turn": list(g.singular_px),
    }


def run(args) -> int:
    out = check_output_path(args.json, (".json",))
    check_distinct({"--json": args.json}, {"calibrated": args.calibrated, "--rig": args.rig})
    near, far = range_from_args(args)
    if not (math.isfinite(args.pitch_mm) and 0 < args.pitch_mm <= 5):
        raise ValueError(f"--pitch-mm must be a screw pitch in (0, 5] mm, got {args.pitch_mm}")
    built, nominal = load_rig(args.calibrated), load_rig(args.rig)
    check_same_design(built, nominal)
    if args.mount is not None:
        from psvs.mount.files import read_mount
        seats = read_mount(args.mount)[1]
    else:
        seats = seats_for(nominal, pitch_mm=args.pitch_mm)
    g = alignment_guide(built, seats, near, far)
    print(format_guide(g))
    if out is not None:
        write_atomic(out, json.dumps(guide_to_dict(g), indent=2) + "\n")
    return 0
