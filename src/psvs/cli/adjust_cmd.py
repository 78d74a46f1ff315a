"""``psvs adjust``: the alignment guide -- which screw of which mirror to turn, which way and how far, so that
a calibrated build's twins land on the same rows (psvs.mount, docs/mount.md)."""
from __future__ import annotations

import json
import sys
from dataclasses import replace

from psvs.cli.common import (
    add_range_arguments,
    add_rig_argument,
    check_distinct,
    check_output_path,
    measuring_rig,
    range_from_args,
)
from psvs.io.atomic import write_atomic
from psvs.mount.guide import alignment_guide, check_aligned
from psvs.mount.report import check_same_design, format_guide, guide_to_dict
from psvs.mount.seats import DEFAULT_PITCH_MM, check_pitch, seats_for


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
    p.add_argument("--pitch-mm", type=float, default=None,
                   help=f"screw pitch, mm per turn (default {DEFAULT_PITCH_MM}: M3 x 0.5, or with --mount the pitch "
                        "its mount.toml lists; given, it is the pitch of the screws fitted)")
    p.add_argument("--mount", metavar="MOUNT_DIR",
                   help="the seats psvs mount wrote there (mount.toml) instead of the default ones")
    p.add_argument("--json", metavar="FILE.json", help="also write the guide here")
    p.set_defaults(run=run)


def run(args) -> int:
    out = check_output_path(args.json, (".json",))
    check_distinct({"--json": args.json}, {"calibrated": args.calibrated, "--rig": args.rig})
    if args.pitch_mm is not None:
        check_pitch(args.pitch_mm, "--pitch-mm")
    built, nominal = measuring_rig(args.calibrated), measuring_rig(args.rig)
    check_same_design(built, nominal)
    near, far = range_from_args(args, built)
    if args.mount is not None:
        from psvs.mount.files import read_mount
        seats = read_mount(args.mount, nominal)[1]
        listed = seats["m1"].pitch_mm
        if args.pitch_mm is not None and args.pitch_mm != listed:  # the screws fitted, not the ones the BOM lists
            seats = {n: replace(seat, pitch_mm=args.pitch_mm) for n, seat in seats.items()}
            print(f"screws of {args.pitch_mm:g} mm pitch (--pitch-mm), not the {listed:g} mm that "
                  f"{args.mount}/mount.toml lists", file=sys.stderr)
    else:
        seats = seats_for(nominal, pitch_mm=DEFAULT_PITCH_MM if args.pitch_mm is None else args.pitch_mm)
    g = check_aligned(alignment_guide(built, seats, near, far))     # turns that do not align: exit 1
    print(format_guide(g))
    if out is not None:
        write_atomic(out, json.dumps(guide_to_dict(g), indent=2) + "\n")
    return 0
