"""``psvs triangulate``: matched pixels (CSV u_l,v_l,u_r,v_r) -> points (CSV X_mm,Y_mm,Z_mm,valid)."""
from __future__ import annotations

import sys

from psvs.cli.common import add_model_argument, add_rig_argument, check_distinct, check_output_path, rig_from_args
from psvs.io.points import points_csv_text, read_matches_csv, write_points_csv
from psvs.measure.triangulate import default_model, triangulate


def add_parser(sub) -> None:
    p = sub.add_parser("triangulate", help="triangulate matched pixels into frame C (mm)",
                       description="Triangulate matched left/right pixels (eqs. 11-17 or exact ray tracing). "
                                   "Input CSV columns u_l,v_l,u_r,v_r (px); output X_mm,Y_mm,Z_mm,valid.")
    add_rig_argument(p)
    p.add_argument("points", metavar="POINTS.csv", help="CSV with header u_l,v_l,u_r,v_r")
    add_model_argument(p)
    p.add_argument("-o", "--output", metavar="OUT.csv", help="write here (atomically) instead of stdout")
    p.set_defaults(run=run)


def run(args) -> int:
    out = check_output_path(args.output, (".csv",))
    check_distinct({"-o": args.output}, {"POINTS.csv": args.points, "--rig": args.rig})
    rig = rig_from_args(args)
    left, right = read_matches_csv(args.points)
    model = args.model or default_model(rig)
    res = triangulate(left, right, rig, model=model)
    if out is None:
        sys.stdout.write(points_csv_text(res.points_mm, res.valid))
    else:
        write_points_csv(out, res.points_mm, res.valid)
        print(f"{out}: {int(res.valid.sum())} of {len(res.valid)} points valid ({model} model)",
              file=sys.stderr)
    return 0
