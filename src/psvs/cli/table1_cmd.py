"""``psvs table1``: the paper's accuracy experiment end to end (Table I, Fig. 10), in simulation."""
from __future__ import annotations

import sys

from psvs.accuracy.table1 import check_start, check_table1, run_table1, table_markdown, write_outputs
from psvs.cli.common import add_rig_argument, measuring_rig
from psvs.io.atomic import check_output_folder
from psvs.io.params import load_rig
from psvs.optics.mirrors import virtual_baseline_mm


def add_parser(sub) -> None:
    p = sub.add_parser("table1", help="reproduce the paper's Table I and Fig. 10 (simulated robot sweep)",
                       description="Render a calibration sweep (or, with --card, views of a hand-held circle-grid "
                                   "card) and the paper's 15 test distances of the circle pattern through the rig "
                                   "(--rig: the true build, which may be misaligned), calibrate from a rough start "
                                   "(or --start NOMINAL.toml), measure, and print our Table I beside the paper's; "
                                   "write table1.csv, table1.md and fig10.png.")
    add_rig_argument(p, required=False)
    p.add_argument("--start", metavar="NOMINAL.toml", help="calibrate from this design (default: a rough guess "
                                                            "of the rig: f +10 %%, b +10 mm, no lens or mirror error)")
    p.add_argument("--card", action="store_true", help="calibrate from 18 views of a hand-held 4x6 card, not a sweep")
    p.add_argument("-o", "--out", metavar="DIR", default="out/table1", help="output folder (default out/table1)")
    p.set_defaults(run=run)


class _Progress:
    """The progress bar on stderr, redrawn in place; :meth:`close` ends its line (a refusal then starts on a
    line of its own, not after the bar: trial 31)."""

    def __init__(self):
        self.open = False

    def __call__(self, i, n, what):
        bar = "#" * (30 * i // n)
        sys.stderr.write(f"\r[{bar:<30}] {i}/{n} {what:<20}")
        self.open = i != n
        if i == n:
            sys.stderr.write("\n")
        sys.stderr.flush()

    def close(self):
        if self.open:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self.open = False


def run(args) -> int:
    out = check_output_folder(args.out)
    start = load_rig(args.start) if args.start else None
    rig, method = measuring_rig(args.rig), "grid" if args.card else "sweep"
    check_table1(rig, method)             # before the progress bar starts: what cannot be done, in one line
    check_start(rig, start)
    progress = _Progress()
    try:
        t = run_table1(rig, progress=progress, start=start, method=method)
    finally:
        progress.close()
    out.mkdir(parents=True, exist_ok=True)
    cal = t.calibration
    b = virtual_baseline_mm(cal.rig)
    what = f"{len(cal.rms_by_image)} card views" if args.card else f"a {len(cal.rms_by_image)}-position sweep"
    print(f"Calibration from {what}, RMS {cal.rms_px:.3f} px: f = {cal.values['focal_length_mm']:.4f} mm, "
          f"|O1 O2| = {b:.3f} mm, plate = {cal.values['plate_thickness_mm']:.2f} mm"
          + (f", robot offset = {cal.sweep['offset_mm']:.2f} mm" if cal.sweep else "") + "\n")
    print(table_markdown(t))
    files = write_outputs(out, t)
    print("Wrote " + ", ".join(str(f) for f in files))
    return 0
