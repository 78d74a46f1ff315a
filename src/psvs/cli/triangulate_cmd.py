"""``psvs triangulate``: matched pixels (CSV u_l,v_l,u_r,v_r) -> points (CSV X_mm,Y_mm,Z_mm,Z_sigma_mm,valid)."""
from __future__ import annotations

import sys

import numpy as np

from psvs.cli.common import (
    add_model_argument,
    add_rig_argument,
    check_distinct,
    check_output_path,
    measuring_model,
    measuring_rig,
)
from psvs.errors import MeasurementError
from psvs.io.points import check_rows_memory, points_csv_text, read_matches_csv, write_points_csv
from psvs.measure.triangulate import (
    EPIPOLAR_TOL_PX,
    MATCH_SIGMA_PX,
    default_model,
    depth_sigma_mm,
    epipolar_gap_px,
    triangulate,
)
from psvs.optics.trace import lit_pairs


def add_parser(sub) -> None:
    p = sub.add_parser("triangulate", help="triangulate matched pixels into frame C (mm)",
                       description="Triangulate matched left/right pixels (eqs. 11-17 or exact ray tracing). "
                                   "Input CSV columns u_l,v_l,u_r,v_r (px); output X_mm,Y_mm,Z_mm,Z_sigma_mm,valid. "
                                   "A pair whose pixels stand more than 2 px off each other's epipolar curve (the "
                                   "exact rays' closest approach) sees two points, not one: invalid. Z_sigma_mm is "
                                   "how far the depth moves for a match error of --match-sigma-px (and, with a "
                                   "closed-form --model that errs on the rig by more than 0.5 %, its own error at the "
                                   "pair: said on stderr); a pair whose "
                                   "depth that error moves by its own size or more (a disparity within twice the "
                                   "noise) is not pinned: invalid.")
    add_rig_argument(p)
    p.add_argument("points", metavar="POINTS.csv", help="CSV with header u_l,v_l,u_r,v_r")
    add_model_argument(p)
    p.add_argument("--match-sigma-px", type=float, default=MATCH_SIGMA_PX, metavar="PX",
                   help=f"the matches' noise along the row, px (default {MATCH_SIGMA_PX:g}: a sub-pixel edge match; "
                        "0.5 for matches to the pixel)")
    p.add_argument("-o", "--output", metavar="OUT.csv", help="write here (atomically) instead of stdout")
    p.set_defaults(run=run)


def _invalid(res, mask: np.ndarray, notes: list[str], say) -> None:
    """Mark the pairs of ``mask`` (N,) bool invalid in ``res`` and, when there are any, add ``say(k, n)`` to
    ``notes`` (k the first of them, n how many; said before they are marked, so it may read their point)."""
    if mask.any():
        notes.append(say(int(np.flatnonzero(mask)[0]), int(mask.sum())))
        res.points_mm[mask] = np.nan
        res.valid[mask] = False


def _unread(left: np.ndarray, right: np.ndarray, rig, res) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Mark invalid in ``res`` the pairs that are no pixels of this camera (NaN, inf or off its image) and those
    where the rig's glass blocks a view (the image shows no twin there): the notes saying so, with the first
    row of each; all those pairs, (N,) bool; and those that are no pixels of the camera, (N,) bool."""
    notes: list[str] = []
    blank = ~(np.all(np.isfinite(left), axis=1) & np.all(np.isfinite(right), axis=1))
    outside = ~blank & ~(_inside(left, rig) & _inside(right, rig))
    dark = ~blank & ~outside & ~lit_pairs(np.nan_to_num(left), np.nan_to_num(right), rig)
    w, h = (int(x) for x in rig.camera.image_size_px)
    for mask, what in ((blank, "are not pixels (NaN or infinite coordinates"),
                       (outside, f"lie outside the camera's {w}x{h} px image (pixel centres 0..{w - 1}, 0..{h - 1}"),
                       (dark, "lie where the rig's glass blocks a view (vignetted")):
        _invalid(res, mask, notes, lambda k, n, what=what: f"{n} pair(s) {what}; row {k + 2}: ({left[k, 0]:.6g}, "
                 f"{left[k, 1]:.6g}) left, ({right[k, 0]:.6g}, {right[k, 1]:.6g}) right)")
    return notes, blank | outside | dark, blank | outside


def _inside(px: np.ndarray, rig) -> np.ndarray:
    """(N,) bool: the pixels (N, 2) that lie on the camera's image (within half a pixel of its edge pixels'
    centres)."""
    w, h = rig.camera.image_size_px
    return (px[:, 0] >= -0.5) & (px[:, 0] <= w - 0.5) & (px[:, 1] >= -0.5) & (px[:, 1] <= h - 0.5)


def run(args) -> int:
    out = check_output_path(args.output, (".csv",))
    check_distinct({"-o": args.output}, {"POINTS.csv": args.points, "--rig": args.rig})
    rig = measuring_rig(args.rig)
    noted = measuring_model(args, rig)
    check_rows_memory(args.points)        # before the rows are read: each costs about a kB through the models
    left, right = read_matches_csv(args.points)
    if len(left) == 0:
        raise ValueError(f"{args.points}: no pairs to triangulate (a header and no rows)")
    model = args.model or default_model(rig)
    res = triangulate(left, right, rig, model=model)
    notes, unread, no_pixel = _unread(left, right, rig, res)    # why rows are invalid: printed, or the refusal's reason
    lost = ~res.valid & ~unread
    if lost.any():            # rays that meet behind the rig or not at all: not a pair of this rig's twins
        k = int(np.flatnonzero(lost)[0])
        swapped = " (u_l and u_r swapped?)" if left[k, 0] - right[k, 0] <= 0 else ""
        notes.append(f"{int(lost.sum())} pair(s) do not triangulate in front of the rig (row {k + 2}: disparity "
                     f"u_l - u_r {left[k, 0] - right[k, 0]:.6g} px{swapped})")
    gap = epipolar_gap_px(left, right, rig)
    off = res.valid & ~(gap <= EPIPOLAR_TOL_PX)        # not twins: the pixels see two different points
    _invalid(res, off, notes, lambda k, n: f"{n} pair(s) stand more than {EPIPOLAR_TOL_PX:g} px off their twin's "
             f"epipolar curve (row {k + 2}: {gap[k]:.1f} px): not twins")
    sigma = depth_sigma_mm(left, right, rig, model, args.match_sigma_px)
    if noted:            # a closed form that errs on this rig (asked, or its default): its error at each pair counts
        exact = triangulate(left, right, rig, model="exact")
        own = np.abs(res.points_mm[:, 2] - exact.points_mm[:, 2])
        sigma = np.where(exact.valid, np.hypot(sigma, own), sigma)
    loose = res.valid & ~(sigma < res.points_mm[:, 2])
    _invalid(res, loose, notes, lambda k, n: f"{n} pair(s) have a disparity within twice the match noise "
             f"({args.match_sigma_px:g} px): their depth is not pinned (row {k + 2}: Z {res.points_mm[k, 2]:.0f} "
             f"mm, +-{sigma[k]:.0f} mm)")
    sigma[~res.valid] = np.nan
    if not res.valid.any():     # every row no pixel of this camera: bad input (2); else the data cannot (1)
        raise (ValueError if no_pixel.all() else MeasurementError)(
            f"none of the {len(res.valid)} pair(s) gives a point: {'; '.join(notes)}")
    for note in notes:
        print(f"{note}, marked invalid", file=sys.stderr)
    if out is None:
        sys.stdout.write(points_csv_text(res.points_mm, res.valid, sigma))
    else:
        write_points_csv(out, res.points_mm, res.valid, sigma)
        print(f"{out}: {int(res.valid.sum())} of {len(res.valid)} points valid ({model} model)",
              file=sys.stderr)
    return 0
