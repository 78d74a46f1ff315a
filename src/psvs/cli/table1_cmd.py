"""``psvs table1``: the paper's accuracy experiment end to end (Table I, Fig. 10), in simulation."""
from __future__ import annotations

import sys
from pathlib import Path

from psvs.calibrate.table1 import run_table1, table_markdown, write_outputs
from psvs.cli.common import add_rig_argument, rig_from_args


def add_parser(sub) -> None:
    p = sub.add_parser("table1", help="reproduce the paper's Table I and Fig. 10 (simulated robot sweep)",
                       description="Render a calibration sweep and the paper's 15 test distances of the circle "
                                   "pattern through the rig, calibrate from a rough start, measure, and print our "
                                   "Table I beside the paper's; write table1.csv, table1.md and fig10.png.")
    add_rig_argument(p, required=False)
    p.add_argument("-o", "--out", metavar="DIR", default="out/table1", help="output folder (default out/table1)")
    p.set_defaults(run=run)


def _progress(i, n, what):
    bar = "#" * (30 * i // n)
    sys.stderr.write(f"\r[{bar:<30}] {i}/{n} {what:<20}")
    if i == n:
        sys.stderr.write("\n")
    sys.stderr.flush()


def run(args) -> int:
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"output folder {out} is a file")
    out.mkdir(parents=True, exist_ok=True)
    t = run_table1(rig_from_args(args), progress=_progress)
    cal = t.calibration
    print(f"Calibration ({len(cal.used)} images, RMS {cal.rms_px:.3f} px): f = {cal.values['focal_length_mm']:.4f} mm, "
          f"b = {cal.values['baseline_mm']:.3f} mm, plate = {cal.values['plate_thickness_mm']:.2f} mm, "
          f"offset = {cal.offset_mm:.2f} mm\n")
    print(table_markdown(t))
    files = write_outputs(out, t)
    print("Wrote " + ", ".join(str(f) for f in files))
    return 0
