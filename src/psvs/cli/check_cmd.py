"""``psvs check``: does the calibration still hold? The twins' row offsets on ordinary frames, a verdict and
which mirrors explain a drift (psvs.health, docs/health.md)."""
from __future__ import annotations

import json
import math
import sys

from psvs.cli.common import (
    add_range_arguments,
    add_rig_argument,
    check_distinct,
    check_output_path,
    measuring_rig,
    range_from_args,
)
from psvs.health.check import TOLERANCE_PX, check_frames
from psvs.io.atomic import output_batch, write_atomic
from psvs.io.images import read_grey

#: Exit statuses: healthy 0, cannot judge 1 (as any measurement the data cannot give), drifted 3.
DRIFTED_STATUS = 3


def add_parser(sub) -> None:
    p = sub.add_parser("check", help="is the calibration still the rig's? twins' rows on ordinary frames",
                       description="From ordinary frames of any textured scene (no target, no known distance): "
                                   "how far the twins stand off their rows under the rig's calibration (RMS and "
                                   "largest, px, of the smooth field a moved mirror makes), on how many tiles, "
                                   "and a verdict: healthy (exit 0), drifted (exit 3; with the mirrors whose "
                                   "tilts best explain it) or cannot judge (exit 1, saying what it needs). "
                                   "docs/health.md.")
    p.add_argument("frames", nargs="+", metavar="FRAME", help="complex images (PNG, JPEG, BMP, TIFF, PNM)")
    add_rig_argument(p)
    add_range_arguments(p)
    p.add_argument("--tolerance-px", type=float, default=TOLERANCE_PX,
                   help=f"the field's RMS a healthy calibration stays within, px (default {TOLERANCE_PX:g})")
    p.add_argument("--json", action="store_true", help="print the check as one JSON object instead")
    p.add_argument("--map", metavar="OUT.png", help="also draw where in the field the twins stand off their rows")
    p.set_defaults(run=run)


def run(args) -> int:
    out = check_output_path(args.map, (".png",))
    frames_in = {f"frame {k + 1}": f for k, f in enumerate(args.frames)}
    check_distinct({"--map": args.map}, {"--rig": args.rig, **frames_in})
    if not (math.isfinite(args.tolerance_px) and args.tolerance_px > 0):
        raise ValueError(f"--tolerance-px must be a number > 0 px, got {args.tolerance_px}")
    rig = measuring_rig(args.rig)
    near, far = range_from_args(args, rig)
    frames = [read_grey(f, expect_size=rig.camera.image_size_px) for f in args.frames]
    check = check_frames(frames, rig, near, far, args.tolerance_px)
    from psvs.health.explain import explain_drift, explanation_line
    found = explain_drift(check, rig, near, far)
    if out is not None and check.verdict != "cannot judge":      # a refusal writes nothing
        from psvs.health.figure import offset_figure
        with output_batch():
            write_atomic(out, offset_figure(check))
    from psvs.health.unseen import not_checked_line
    unseen = not_checked_line(rig, far)         # what a healthy verdict did not judge
    if args.json:
        d = check.as_dict() | {"explained_by": [e.as_dict() for e in found], "not_checked": unseen}
        print(json.dumps(d))
    elif check.verdict != "cannot judge":       # a refusal is said once, on stderr
        print(f"{check.verdict}: {check.reason}")
        if found:
            print(f"best explained by {explanation_line(found, check.tolerance_px)}")
        if check.verdict == "healthy":
            print(unseen)
    if check.verdict == "cannot judge":
        print(f"psvs check: cannot judge: {check.reason}", file=sys.stderr)
        return 1
    return DRIFTED_STATUS if check.verdict == "drifted" else 0
