"""``psvs measure circles``: Table I's columns (Z, circle diameters, first-last distance) from one image."""
from __future__ import annotations

import json

from psvs.accuracy.pattern_measure import check_pattern_sizes, measure_pattern
from psvs.cli.common import (
    add_model_argument,
    add_range_arguments,
    add_rig_argument,
    measuring_model,
    measuring_rig,
    range_from_args,
)
from psvs.io.images import check_frame_size, read_grey


def add_parser(sub) -> None:
    p = sub.add_parser("measure", help="measure the paper's circle pattern (Table I columns)",
                       description="Measure the paper's accuracy pattern (Fig. 9: 5 circles of 10 mm, 20 mm apart) "
                                   "in a complex image: depth Z, the circles' diameters and the distance between "
                                   "the first and the last circle centres. What is found is checked against the "
                                   "pattern (docs/calibration.md): --count circles per view, paired by the rig's "
                                   "geometry (twins on their epipolar curves within the working range, equal "
                                   "spacing along the row, the diameters, all within what the pixels resolve at "
                                   "that depth); no consistent pairing, more than one, or a disagreement exits 1 "
                                   "naming the check.")
    p.add_argument("target", choices=["circles"], help="what to measure")
    p.add_argument("image", metavar="IMAGE", help="complex image (PNG, grey)")
    add_rig_argument(p)
    add_model_argument(p, default="exact")
    p.add_argument("--count", type=int, default=5, help="circles in the pattern (default 5)")
    p.add_argument("--spacing-mm", type=float, default=20.0, help="centre-to-centre spacing of the circles, mm "
                                                                   "(default 20, the paper's)")
    p.add_argument("--diameter-mm", type=float, default=10.0, help="diameter of the circles, mm (default 10, "
                                                                    "the paper's)")
    add_range_arguments(p, "working range (where the pattern may be; it sets the circles' sizes and disparities)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a summary")
    p.set_defaults(run=run)


def prepare(args, image=None) -> tuple:
    """Every check of the arguments and the image before any work: (image, rig, (near, far) mm).
    ``image``: already read (a frame of ``psvs batch``), else read from args.image."""
    rig = measuring_rig(args.rig)
    check_pattern_sizes(args.spacing_mm, args.diameter_mm, ("--spacing-mm", "--diameter-mm"))
    z_mm = range_from_args(args, rig)
    measuring_model(args, rig, *z_mm)
    size = rig.camera.image_size_px
    image = read_grey(args.image, expect_size=size) if image is None else check_frame_size(image, size, args.image)
    return image, rig, z_mm


def compute(args, image=None):
    """The measurement (:class:`~psvs.accuracy.pattern_measure.PatternMeasurement`); MeasurementError when the
    pattern is not found as asked."""
    image, rig, z_mm = prepare(args, image)
    return measure_pattern(image, rig, model=args.model, count=args.count,
                           spacing_mm=args.spacing_mm, diameter_mm=args.diameter_mm, z_mm=z_mm)


def run(args) -> int:
    m = compute(args)
    if args.json:
        print(json.dumps(m.to_dict()))
    else:
        print(f"Z = {m.Z_mm:.3f} mm, circle diameter = {m.diameter_mm:.3f} mm "
              f"({', '.join(f'{d:.3f}' for d in m.diameters_mm)}), first-last distance = "
              f"{m.first_last_distance_mm:.3f} mm")
    return 0
