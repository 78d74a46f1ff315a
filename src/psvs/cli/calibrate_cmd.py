"""``psvs calibrate``: calibrate a build from hand-held card views and/or the paper's robot sweep."""
from __future__ import annotations

import math
import sys

from psvs.calibrate.bundle import ASPECT, ASPECT_SCORE_LIMIT, PRIOR_SIGMA
from psvs.calibrate.folder import calibrate_folder
from psvs.cli.common import add_rig_argument, check_distinct, check_output_path, rig_from_args
from psvs.errors import MeasurementError
from psvs.io.atomic import check_output_folder, output_batch
from psvs.io.params import rig_template, save_rig


def add_parser(sub) -> None:
    p = sub.add_parser("calibrate", help="calibrate the rig from views of a card (or a robot sweep)",
                       description="Calibrate a build from the complex images in DIR: views of a hand-held "
                                   "card at free poses (DIR/target.toml describes it: circle_grid, "
                                   "asymmetric_circle_grid or charuco; its two copies may interleave) and/or the "
                                   "paper's robot sweep of the circle pattern (DIR/sweep.csv: image,position_mm). "
                                   "A bundle adjustment over the exact optics, starting from the nominal design "
                                   "(--rig), solves the lens (f, principal point, k1 k2 p1 p2 k3), the plate, "
                                   "each mirror's tilts and the far mirrors' shifts, and every pose.")
    p.add_argument("folder", metavar="DIR", help="folder with the PNG images and target.toml and/or sweep.csv")
    add_rig_argument(p)
    p.add_argument("-o", "--output", metavar="RIG.toml", required=True,
                   help="calibrated rig file (TOML: in the --rig file's comments and layout; or .json)")
    p.add_argument("--report", metavar="DIR",
                   help="write residuals.csv, residuals.png and vertical_disagreement.png here (created if missing)")
    p.add_argument("--adjust", nargs="?", const=True, default=None, metavar="MOUNT_DIR",
                   help="also print the alignment guide: the screw turns on the seats of the --rig design's "
                        "mirrors (M3 x 0.5; or those psvs mount wrote to MOUNT_DIR) that bring the build's twins "
                        "onto the same rows over 400-1200 mm (as psvs adjust OUTPUT --rig RIG; docs/mount.md)")
    p.set_defaults(run=run)


def _fmt(name: str, value: float, sigma: float) -> str:
    if name.endswith("_rad"):
        return f"  {name[:-4] + '_deg':<22}{math.degrees(value):12.5f}  +- {math.degrees(sigma):.5f}"
    return f"  {name:<22}{value:12.5f}  +- {sigma:.5f}"


def _guide(rig, design, mount_dir) -> str:
    """The alignment guide of the calibrated ``rig`` on the seats of ``design``'s mirrors, or on those of the
    mount in ``mount_dir`` (docs/mount.md)."""
    from psvs.mount.guide import alignment_guide
    from psvs.mount.report import guide_or_refusal
    from psvs.mount.seats import seats_for
    if mount_dir is True:
        return guide_or_refusal(alignment_guide(rig, seats_for(design)))
    from psvs.mount.files import read_mount
    return guide_or_refusal(alignment_guide(rig, read_mount(mount_dir, design)[1]))


def run(args) -> int:
    out = check_output_path(args.output, (".toml", ".json"))
    report = check_output_folder(args.report, "report folder") if args.report is not None else None
    check_distinct({"-o": args.output}, {"--rig": args.rig, "DIR": args.folder})
    start = rig_from_args(args)
    template = rig_template(args.rig)    # the nominal file's comments and layout, for the calibrated file
    if args.adjust not in (None, True):  # a mount folder: read before the work
        from psvs.mount.files import read_mount
        read_mount(args.adjust, start)
    res = calibrate_folder(args.folder, start)
    b = res.bundle
    if not b.success:   # no calibration, so no table of its values (a trial: 35 lines of them, then the refusal)
        raise MeasurementError(f"the bundle adjustment {b.message}: no rig written (views of more than one build, "
                               "a card unlike its target.toml, a start rig far from the build, or cards all at "
                               "one distance and square to the camera?)")
    for name, reason in sorted(res.skipped.items()):
        print(f"skipped {name}: {reason}", file=sys.stderr)
    print(f"used {len(res.used)} image(s) ({res.kinds})")
    print(f"reprojection RMS {b.rms_px:.4f} px (left view {b.rms_by_view['left']:.4f}, right view "
          f"{b.rms_by_view['right']:.4f})")
    for name, rms in b.rms_by_image.items():
        print(f"  {name:<28}{rms:8.4f} px")
    print("parameters (1-sigma):")
    for name, value in b.values.items():
        held = "  (not seen by these images: held near nominal by its prior)" if name in b.held_by_prior else ""
        if name == ASPECT and b.aspect_score is not None:
            print(f"  {name:<22}{value:12.5f}  held at the start rig's: the views show no other (score "
                  f"{b.aspect_score:.1f} <= {ASPECT_SCORE_LIMIT:g})")
            continue
        sigma = b.sigma[name]
        if held and not sigma > 0:          # held at the design outright (a sweep): as uncertain as its prior
            sigma = PRIOR_SIGMA[name]
        print(_fmt(name, value, sigma) + held)
    print(f"  {'baseline_mm (|O1 O2|)':<22}{res.baseline_mm:12.5f}  +- {res.baseline_sigma_mm:.5f}")
    if "grid" in res.used.values() and not b.sweep:    # the card's print is the one length the images have
        print("  every length (the baseline, depth) scales with the card's spacing as target.toml states it: a card "
              "printed 1 % large reads them all 1 % long, which these +- leave out (measure the printed card)")
    if b.sweep:
        print(f"  robot offset: Z = reading + {b.sweep['offset_mm']:.3f} mm")
    if b.held_by_prior:
        priors = ", ".join(f"{n[:-4]}_deg +-{math.degrees(PRIOR_SIGMA[n]):.2g}" if n.endswith("_rad")
                           else f"{n} +-{PRIOR_SIGMA[n]:g}" for n in b.held_by_prior)
        print(f"{len(b.held_by_prior)} parameter(s) held near nominal by their priors ({priors}): "
              "the images do not show them; more card views, tilted and over the whole field, would pin them down")
    print(f"bundle adjustment {b.message}")
    # before any file: a guide that fails writes none
    guide = _guide(res.rig, start, args.adjust) if args.adjust else None
    with output_batch():   # the rig file and the report land together
        save_rig(res.recorded_rig(), out, template)
        written = []
        if report is not None:
            from psvs.calibrate.report import write_report
            report.mkdir(parents=True, exist_ok=True)
            written = write_report(report, b)
    for f in written:
        print(f"wrote {f}")
    if guide is not None:
        print(guide)
    return 0
