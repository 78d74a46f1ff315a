"""``psvs match``: edges of a complex image matched (the paper's seeded algorithm or automatic), triangulated."""
from __future__ import annotations

import sys

from psvs.cli.common import (
    add_model_argument,
    add_pipeline_argument,
    add_range_arguments,
    add_rig_argument,
    check_distinct,
    check_output_path,
    measuring_model,
    measuring_rig,
    parse_seed,
    pipeline_from_args,
    range_from_args,
)
from psvs.errors import MeasurementError
from psvs.health.check import refuse_if_drifted
from psvs.io.atomic import output_batch
from psvs.io.images import check_frame_size, read_grey
from psvs.match.auto import MIN_TWIN_LAG_PX
from psvs.match.correspondence import MatchParams, match_image, rows_unshown
from psvs.match.export import write_csv, write_json, write_ply
from psvs.optics.trace import trace_pixels


def add_parser(sub) -> None:
    p = sub.add_parser("match", help="match edges on a complex image and triangulate them",
                       description="Find corresponding edges of the left and right views in a complex image: "
                                   "the paper's algorithm from a seed pixel on a left-view edge (--seed), or "
                                   "every edge with its twin (--auto). Writes pairs with disparities and 3-D "
                                   "points (JSON; optional CSV, PLY and Fig. 7/8-like figures).")
    p.add_argument("image", metavar="IMAGE", help="complex image (PNG, grey)")
    add_rig_argument(p)
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--seed", metavar="U,V", help="a pixel on a left-view edge (the paper's double-click)")
    mode.add_argument("--auto", action="store_true", help="pair every edge with its twin automatically")
    add_pipeline_argument(p)
    p.add_argument("-o", "--output", metavar="OUT.json", required=True, help="pairs and unmatched edges (JSON)")
    p.add_argument("--csv", metavar="OUT.csv", help="one row per matched pixel")
    p.add_argument("--ply", metavar="OUT.ply", help="3-D points")
    p.add_argument("--figures", metavar="DIR", help="write fig7_views.png and fig8_disparity.png here")
    add_range_arguments(p)
    add_model_argument(p)
    p.add_argument("--n-seeds", type=int, help="seeds on the corresponding edge, 2-100 (default 10)")
    p.add_argument("--no-subpixel", action="store_true", help="keep integer pixel positions")
    p.set_defaults(run=run)


def prepare(args, image=None) -> tuple:
    """Every check of the arguments and inputs before any work: (the output paths, the matching's
    arguments). ``image``: already read (a frame of ``psvs batch``), else read from args.image."""
    out = check_output_path(args.output, (".json",))
    csv_path = check_output_path(args.csv, (".csv",))
    ply_path = check_output_path(args.ply, (".ply",))
    check_distinct({"-o": args.output, "--csv": args.csv, "--ply": args.ply},
                   {"IMAGE": args.image, "--rig": args.rig, "--pipeline": args.pipeline})
    if args.figures is not None:
        from pathlib import Path
        if not Path(args.figures).is_dir():
            raise FileNotFoundError(f"figures folder does not exist: {args.figures}")
    seed = parse_seed(args.seed, whole=True)
    if args.auto and args.n_seeds is not None:
        raise ValueError("--n-seeds applies to --seed (seeds on the edge the user picked), not to --auto")
    if args.n_seeds is not None and not 2 <= args.n_seeds <= 100:
        raise ValueError(f"--n-seeds must be 2-100, got {args.n_seeds}")
    rig = measuring_rig(args.rig)
    near_mm, far_mm = range_from_args(args, rig)
    measuring_model(args, rig, near_mm, far_mm)
    pipeline = pipeline_from_args(args)
    size = rig.camera.image_size_px
    image = read_grey(args.image, expect_size=size) if image is None else check_frame_size(image, size, args.image)
    if seed is not None and not (-0.5 <= seed[0] <= size[0] - 0.5 and -0.5 <= seed[1] <= size[1] - 0.5):
        raise ValueError(f"the seed ({seed[0]:g}, {seed[1]:g}) is outside the {size[0]}x{size[1]} image")
    if seed is not None and not trace_pixels([seed], rig, "left").valid[0]:
        raise ValueError(f"the seed ({seed[0]:g}, {seed[1]:g}) lies where the rig's glass blocks the left view "
                         "(vignetted: what the image shows there is not that view); pick a pixel on an edge of "
                         "its lit part")
    seeds = {} if args.n_seeds is None else {"n_seeds": args.n_seeds}   # else MatchParams' default
    params = MatchParams(subpixel=not args.no_subpixel, model=args.model, **seeds)
    return (out, csv_path, ply_path), dict(grey=image, rig=rig, seed_px=seed, pipeline=pipeline, near_mm=near_mm,
                                           far_mm=far_mm, params=params)


def compute(args, image=None):
    """The matching and its files: the :class:`~psvs.match.correspondence.MatchResult`."""
    (out, csv_path, ply_path), work = prepare(args, image)
    res = match_image(**work)
    refuse_unanswered(res, work["seed_px"] is not None)
    # the pairs' own rows check sees only the pairs, and where a knock's field crosses zero some pairs fit: on
    # a frame of the misaligned build read through the ideal rig (7 px off), two of three pairs were 170 and
    # 320 mm off; the image's self-check sees the whole field
    check = refuse_if_drifted(work["grey"], work["rig"], work["near_mm"], work["far_mm"])
    unshown = rows_unshown(res, check)       # a check that cannot judge, and no pair on the rows either
    if unshown:
        raise MeasurementError(unshown)
    with output_batch():   # all outputs land together, or none replaces an earlier file
        write_json(out, res)
        if csv_path:
            write_csv(csv_path, res)
        if ply_path:
            write_ply(ply_path, res)
        if args.figures:
            from psvs.match.figures import write_figures
            write_figures(args.figures, res, work["grey"])
    return res


#: The unpaired edges' labels the summary names (the rest are in the JSON file: a noisy edge map made a 45 kB
#: line of 7742 labels).
SHOWN_UNMATCHED = 20


def refuse_unanswered(res, seeded: bool) -> None:
    """MeasurementError (nothing written) when the match paired nothing: no twin stands above chance, or
    none was found -- why, in figures."""
    if res.pairs:
        return
    what = "the seed's edge has no twin" if seeded else "no edge pairs with a twin"
    if res.edge_noise is not None and res.edge_noise.noise:
        raise MeasurementError(f"{what} to be trusted: {res.edge_noise.describe()}")
    if res.rows is not None and res.rows.refuses:
        raise MeasurementError(f"{what} on the rig's rows: {res.rows.describe()}")
    if not res.chance.answered:
        raise MeasurementError(f"{what} beyond chance: {res.chance.describe()}")
    lo, hi = res.disparity_range_px
    if seeded:
        if res.chance.twins_below:
            raise MeasurementError(f"{what} beyond chance at the working range's disparities {lo:.0f}..{hi:.0f} "
                                   "px, or its pixels twin as strongly or more below them (a scene beyond the far "
                                   f"limit: widen the range) ({res.chance.describe()})")
        raise MeasurementError(f"{what} beyond chance at the working range's disparities {lo:.0f}..{hi:.0f} px: "
                               "the twin it pairs with agrees on too few rows to stand alone, and the automatic "
                               f"matcher pairs no edge there that backs it ({res.chance.describe()})")
    raise MeasurementError(f"{what} at the working range's disparities {lo:.0f}..{hi:.0f} px: every candidate "
                           f"failed the matcher's rules or stood alone within chance ({res.chance.describe()})")


def summary_row(res) -> dict:
    """What the command prints, as scalars (a row of ``psvs batch``'s results)."""
    return {"pairs": len(res.pairs), "unmatched": len(res.unmatched),
            "pixel_pairs": int(sum(len(p) for p in res.pairs))}


def run(args) -> int:
    res = compute(args)
    if res.disparity_range_px[0] <= MIN_TWIN_LAG_PX:
        print(f"psvs match: warning: disparities under {MIN_TWIN_LAG_PX:g} px were not searched (an edge's twin "
              "there cannot be told from the edge itself): the far end of the range was not measured", file=sys.stderr)
    for k, p in enumerate(res.pairs):
        print(f"edge {k}: {len(p)} pixel pairs, disparity {p.shape_disparity_px:.0f} px, "
              f"median Z {p.median_z_mm():.1f} mm")
    if res.unmatched:
        labels = [str(u.label) for u in res.unmatched]
        more = f" ... and {len(labels) - SHOWN_UNMATCHED} more (all in {args.output})" \
            if len(labels) > SHOWN_UNMATCHED else ""
        print(f"{len(labels)} edge(s) without a twin: {', '.join(labels[:SHOWN_UNMATCHED])}{more}")
    print(f"chance: {res.chance.describe()}")
    return 0
