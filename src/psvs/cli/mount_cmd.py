"""``psvs mount``: the printable mirror mount for a designed rig -- STEP, STL, a dimensioned drawing, the
bill of materials and the seats' screws (psvs.mount, docs/mount.md), checked against the optics before
anything is written."""
from __future__ import annotations

import sys

from psvs.cli.common import add_range_arguments, add_rig_argument, range_from_args, rig_from_args
from psvs.io.atomic import check_output_folder
from psvs.mount.layout import INTERFACES, MountError, MountParams

FILES = ("mount.step", "mount.stl", "drawing.svg", "drawing.png", "bom.csv", "mount.toml")


def add_parser(sub) -> None:
    d = MountParams()
    p = sub.add_parser("mount", help="a printable, adjustable mirror mount (STEP, STL, drawing, BOM)",
                       description="Design the mount that holds the rig's four mirrors: a tray with one carrier "
                                   "per mirror, each mirror on three contacts (a pivot and two M3 screws that "
                                   "trim its two tilts), and the camera's interface. Checked against the optics "
                                   "first (no field ray may meet it, the glass lands on its designed planes, "
                                   "the STL is one closed shell, no wall under the minimum); then DIR gets "
                                   + ", ".join(FILES)
                                   + ". Needs the extra psvs[cad]. Exit status 1 when the layout cannot be "
                                   "built (nothing written), 2 on bad input.")
    add_rig_argument(p)
    add_range_arguments(p)
    p.add_argument("-o", "--output", metavar="DIR", required=True, help="output folder (created if missing)")
    p.add_argument("--interface", choices=INTERFACES, default=d.interface,
                   help="the camera: a clamp on the lens barrel, or a plate on a C or CS mount camera's front "
                        f"(default {d.interface})")
    p.add_argument("--lens-diameter-mm", type=float, default=d.lens_diameter_mm,
                   help=f"the lens barrel's diameter (default {d.lens_diameter_mm:g})")
    p.add_argument("--lens-front-mm", type=float, default=d.lens_front_mm,
                   help="the barrel's front face ahead of the entrance pupil O (default 0)")
    p.add_argument("--flange-mm", type=float, default=d.flange_mm,
                   help=f"c/cs: the camera's front face behind O (default {d.flange_mm:g})")
    p.add_argument("--hole-square-mm", type=float, default=d.hole_square_mm,
                   help=f"c/cs: the camera's four front M3 holes on this square (default {d.hole_square_mm:g})")
    p.add_argument("--margin-mm", type=float, default=d.margin_mm,
                   help="every mirror's border beyond its chief rays, and the free space around the light: about "
                        "half the lens's entrance pupil (psvs design --margin-mm; default 0)")
    p.add_argument("--wall-mm", type=float, default=d.wall_mm,
                   help=f"the thinnest wall your printer makes (default {d.wall_mm:g})")
    p.add_argument("--clearance-mm", type=float, default=d.clearance_mm,
                   help=f"your printer's clearance, added to holes and fits (default {d.clearance_mm:g})")
    p.add_argument("--pitch-mm", type=float, default=d.pitch_mm,
                   help=f"the seats' screw pitch, mm per turn (default {d.pitch_mm:g}: M3 x 0.5)")
    p.add_argument("--m1-border-mm", type=float, default=d.m1_border_mm,
                   help=f"the M1 plate's extra height above and below its light, for its contacts "
                        f"(default {d.m1_border_mm:g})")
    p.set_defaults(run=run)


def params_from_args(args) -> MountParams:
    return MountParams(interface=args.interface, lens_diameter_mm=args.lens_diameter_mm,
                       lens_front_mm=args.lens_front_mm, flange_mm=args.flange_mm,
                       hole_square_mm=args.hole_square_mm, wall_mm=args.wall_mm, clearance_mm=args.clearance_mm,
                       pitch_mm=args.pitch_mm, m1_border_mm=args.m1_border_mm, margin_mm=args.margin_mm)


def run(args) -> int:
    from psvs.mount.cad import MissingExtra, require_cad
    params = params_from_args(args)
    rig = rig_from_args(args)
    near, far = range_from_args(args, rig)
    folder = check_output_folder(args.output)
    try:
        require_cad()
    except MissingExtra as exc:
        print(f"psvs mount: {exc}", file=sys.stderr)
        return 2
    from psvs.mount.build import make_mount
    try:
        made = make_mount(rig, params, near, far)
    except MountError as exc:
        print(f"psvs mount: cannot build: {exc}", file=sys.stderr)
        return 1
    from psvs.io.atomic import output_batch, write_atomic
    folder.mkdir(parents=True, exist_ok=True)
    with output_batch():
        for name in FILES:
            write_atomic(folder / name, made.files[name])
    c = made.checks
    print(f"mount for {args.rig or 'default'}: {made.layout.volume_mm3 / 1000:.1f} cm^3, one solid; "
          f"{c.rays} field rays, {c.blocked} blocked; glass on its planes within "
          f"{max(c.glass_error_mm.values()):.3f} mm; STL one closed shell; thinnest wall {c.min_wall_mm:.2f} mm")
    print(f"wrote {', '.join(str(folder / n) for n in FILES)}")
    return 0
