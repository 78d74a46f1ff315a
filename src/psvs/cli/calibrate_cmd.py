"""``psvs calibrate``: calibrate a rig from a robot sweep of the paper's circle pattern."""
from __future__ import annotations

import sys

from psvs.calibrate.sweep import calibrate_folder
from psvs.cli.common import add_rig_argument, check_output_path, rig_from_args
from psvs.io.params import save_rig


def add_parser(sub) -> None:
    p = sub.add_parser("calibrate", help="calibrate the rig from a robot sweep of the circle pattern",
                       description="Calibrate f, the principal point, the baseline, the M1 plate's thickness and "
                                   "the robot's Z offset from images of the paper's pattern moved along Z. "
                                   "SWEEP_DIR holds the images and sweep.csv (columns image,position_mm).")
    p.add_argument("sweep", metavar="SWEEP_DIR", help="folder with the images and sweep.csv")
    add_rig_argument(p)
    p.add_argument("-o", "--output", metavar="RIG.toml", required=True, help="calibrated rig file")
    p.set_defaults(run=run)


def run(args) -> int:
    out = check_output_path(args.output, (".toml", ".json"))
    res = calibrate_folder(args.sweep, rig_from_args(args))
    for name, reason in res.skipped.items():
        print(f"skipped {name}: {reason}", file=sys.stderr)
    print(f"used {len(res.used)} image(s): {', '.join(res.used)}")
    for k, v in res.values.items():
        print(f"  {k:<20}{v:12.5f}  +- {res.sigma[k]:.5f}")
    print(f"reprojection RMS {res.rms_px:.4f} px; solver: {res.message}")
    save_rig(res.rig, out)
    return 0 if res.success else 1
