"""``psvs design``: size the four mirrors for a rig, check the layout, print and write the mirror table."""
from __future__ import annotations

import json
import math

from psvs.cli.common import (
    add_range_arguments,
    add_rig_argument,
    check_distinct,
    check_output_path,
    range_from_args,
    rig_from_args,
)
from psvs.io.atomic import output_batch, write_atomic
from psvs.io.params import dumps_rig, rig_to_dict
from psvs.io.tomlfile import dumps_toml
from psvs.measure.tolerance import Sensitivity, tolerance_analysis
from psvs.optics.design import MAX_BLOCKED_SHARE, MirrorDesign, design_mirrors, share_words
from psvs.optics.mirrors import front_z_mm
from psvs.optics.obstruction import sized_shares
from psvs.optics.plate import derived_refraction_terms
from psvs.optics.solids import finite_solids


def add_parser(sub) -> None:
    p = sub.add_parser("design", help="size and check the four mirrors (eqs. 1-8 and more)",
                       description="Size all four mirrors so the rig's field equals the camera's, check that no "
                                   "mirror or the M1 plate blocks a light path, and print the mirror table. "
                                   "Exit status 1 when the layout is blocked, 2 on bad input.")
    add_rig_argument(p)
    add_range_arguments(p)
    p.add_argument("--margin-mm", type=float, default=0.0,
                   help="extra border on every mirror side, e.g. half the lens entrance pupil (default 0)")
    p.add_argument("--no-search", action="store_true", help="skip the search for clear M1/M2 positions")
    p.add_argument("--tolerance", action="store_true",
                   help="also say how far each mirror's mounting error (0.1 deg, 0.1 mm) moves the views: rows "
                        "apart (px) and depth error before calibration (mm), and the error worth 1 px")
    p.add_argument("-o", "--output", metavar="TABLE.json|.toml", help="write the mirror table here")
    p.add_argument("--rig-out", metavar="RIG.toml|.json", help="write the rig with the designed mirror extents")
    p.set_defaults(run=run)


def design_to_dict(d: MirrorDesign) -> dict:
    """The mirror table and checks as plain data (no None: TOML has no null)."""
    out = {"mirrors": [], "checks": {"ok": d.ok, "verdict": d.verdict, "problems": d.problems,
                                     "blocked_share": dict(d.blocked_share or {})}}
    for s in d.mirrors:
        w, h = s.extent.size_mm
        out["mirrors"].append({
            "name": s.name.upper(), "width_mm": w, "height_mm": h,
            "along_mm": list(s.extent.along_mm), "height_range_mm": list(s.extent.height_mm),
            "anchor_mm": list(s.anchor_mm), "centre_mm": list(s.centre_mm), "normal": list(s.normal),
            "axis_distance_mm": s.axis_distance_mm, "eq6_length_mm": s.eq6_length_mm,
        })
    if d.m2_window_mm is not None:
        out["checks"]["m2_clear_range_mm"] = list(d.m2_window_mm)
    if d.suggestion_mm is not None:
        out["checks"]["suggested_m1_axis_distance_mm"] = d.suggestion_mm[0]
        out["checks"]["suggested_m2_axis_distance_mm"] = d.suggestion_mm[1]
    if d.search_note:
        out["checks"]["search_note"] = d.search_note
    if d.working_range is not None:
        wr = d.working_range
        out["working_range"] = {
            "near_mm": wr.near_mm, "far_mm": wr.far_mm, "disparity_px": list(wr.disparity_px),
            "depth_per_px_mm": list(wr.depth_per_px_mm), "overlap_start_mm": wr.overlap_start_mm}
    out["rig"] = rig_to_dict(d.rig)
    return out


def tolerance_to_dict(rows: list[Sensitivity]) -> list[dict]:
    """Tolerance rows as plain data: steps and the 1-px errors in degrees or mm (the file's units)."""
    out = []
    for r in rows:
        deg = r.unit == "rad"
        conv = math.degrees if deg else float
        key = "deg" if deg else "mm"
        out.append({"part": r.part, "error": r.component, f"step_{key}": conv(r.step),
                    "rows_apart_px_max": r.row_px_max, "rows_apart_px_mean": r.row_px_mean,
                    "depth_error_mm_mean": r.depth_mm_mean, "depth_error_mm_max": r.depth_mm_max,
                    f"error_for_1px_{key}": conv(r.per_px) if math.isfinite(r.per_px) else -1.0})
    return out


def format_tolerance(rows: list[Sensitivity], near_mm: float, far_mm: float) -> str:
    """The tolerance table (each error alone, before calibration)."""
    lines = ["", f"Tolerance: each error alone, points over the shared field at {near_mm:g}-{far_mm:g} mm, "
                 "the nominal rig triangulating (no calibration)",
             f"{'part':<11}{'error':<26}{'step':>9}{'rows apart px':>16}{'depth error mm':>17}{'1 px of rows':>15}",
             f"{'':<11}{'':<26}{'':>9}{'max':>8}{'mean':>8}{'mean':>8}{'max':>9}{'at':>15}"]
    for r in rows:
        deg = r.unit == "rad"
        step = f"{math.degrees(r.step):.2g} deg" if deg else f"{r.step:.2g} mm"
        one = (f"{math.degrees(r.per_px):.3f} deg" if deg else f"{r.per_px:.2f} mm") if math.isfinite(r.per_px) \
            else "never"
        lines.append(f"{r.part:<11}{r.component:<26}{step:>9}{r.row_px_max:8.2f}{r.row_px_mean:8.2f}"
                     f"{r.depth_mm_mean:8.2f}{r.depth_mm_max:9.2f}{one:>15}")
    lines.append("Errors add about linearly. Matching along rows needs twins within ~1 px; calibration "
                 "(psvs calibrate) removes the depth error.")
    return "\n".join(lines)


def format_design(d: MirrorDesign, sized: str = "") -> str:
    """A readable mirror table with the checks; ``sized`` a line on the rig file's own mirror sizes, after the
    layout's."""
    rig = d.rig
    a_deg = [math.degrees(x) for x in rig.camera.half_fov_rad]
    lines = [f"Camera: f = {rig.camera.focal_length_mm:g} mm, {rig.camera.image_size_px[0]}x"
             f"{rig.camera.image_size_px[1]} px, half field {a_deg[0]:.2f} x {a_deg[1]:.2f} deg; "
             f"b = {rig.mirrors.baseline_mm:g} mm, omega_1 = {math.degrees(rig.mirrors.angle_rad):g} deg, "
             f"plate d = {rig.mirrors.plate_thickness_mm:g} mm, n = {rig.mirrors.refractive_index:g}",
             "",
             f"{'mirror':<7}{'width':>9}{'height':>9}{'eq.(6)':>9}   {'centre (x, y, z) mm':<26}{'OB':>8}",
             f"{'':<7}{'mm':>9}{'mm':>9}{'mm':>9}   {'':<26}{'mm':>8}"]
    for s in d.mirrors:
        w, h = s.extent.size_mm
        c = ", ".join(f"{v:.2f}" for v in s.centre_mm)
        lines.append(f"{s.name.upper():<7}{w:9.2f}{h:9.2f}{s.eq6_length_mm:9.2f}   ({c}){'':<{max(0, 24 - len(c))}}"
                     f"{s.axis_distance_mm:8.2f}")
    lines.append("")
    lines.append({"clear": "Layout: clear",
                  "vignetted": f"Layout: vignetted ({d.share_words()}: a build of it measures in the rest)",
                  "BLOCKED": f"Layout: BLOCKED ({d.share_words()}: no build)"}[d.verdict])
    lines += [f"  - {p}" for p in d.problems]
    if sized:
        lines.append(sized)
    if d.m2_window_mm is not None:
        lines.append(f"  M2 clears both paths for m2_axis_distance_mm in [{d.m2_window_mm[0]:.2f}, "
                     f"{d.m2_window_mm[1]:.2f}] mm")
    if d.suggestion_mm is not None:
        lines.append(f"  Suggestion: m1_axis_distance_mm = {d.suggestion_mm[0]:.2f}, "
                     f"m2_axis_distance_mm = {d.suggestion_mm[1]:.2f}")
    if d.search_note:
        lines.append(f"  Note: {d.search_note}")
    if d.working_range is not None:
        wr = d.working_range
        lines += ["", f"Working range {wr.near_mm:g}-{wr.far_mm:g} mm: disparity {wr.disparity_px[0]:.1f}-"
                      f"{wr.disparity_px[1]:.1f} px by eq. (12){_through_glass(d.rig, wr.disparity_px)}; "
                      f"1 px of disparity = {wr.depth_per_px_mm[0]:.2f} mm of depth "
                      f"at the near end, {wr.depth_per_px_mm[1]:.2f} mm at the far end; the views overlap "
                      f"from {wr.overlap_start_mm:.0f} mm"]
        if wr.far_mm < wr.overlap_start_mm:
            lines.append(f"  the views never overlap in the working range (from {wr.overlap_start_mm:.0f} mm on): no "
                         "point of it is seen twice; Layout: NO STEREO over this range")
        elif wr.near_mm < wr.overlap_start_mm:
            lines.append(f"  warning: the working range starts before the views overlap ({wr.overlap_start_mm:.0f} mm)")
    return "\n".join(lines)


def _through_glass(rig, disparity_px: tuple[float, float]) -> str:
    """Eq. (12)'s disparities (px, far and near) as the plate makes them on the axis, in words: eq. (15) with
    x_l ~ 0 is eq. (12) with the baseline b + m (m of eq. 15), so each grows by (b + m) / b (the default rig:
    90.4 -> 91.3 px at 1200 mm, which the exact trace gives at the principal point; a trial found design's
    figure 1 % low). '' for a rig without a plate's shift."""
    m = rig.mirrors.refraction_m_mm
    m = derived_refraction_terms(rig)[1] if m is None else m
    if not m:
        return ""
    k = (rig.mirrors.baseline_mm + m) / rig.mirrors.baseline_mm
    return f" ({disparity_px[0] * k:.1f}-{disparity_px[1] * k:.1f} px through the plate, m = {m:.2f} mm of eq. 15)"


def run(args) -> int:
    out = check_output_path(args.output, (".json", ".toml"))
    rig_out = check_output_path(args.rig_out, (".json", ".toml"))
    check_distinct({"-o": args.output, "--rig-out": args.rig_out}, {"--rig": args.rig})
    range_from_args(args)
    if not (math.isfinite(args.margin_mm) and args.margin_mm >= 0):
        raise ValueError(f"--margin-mm must be a finite border >= 0 mm, got {args.margin_mm}")
    rig = rig_from_args(args)
    front = front_z_mm(rig)
    if args.near_mm <= front:         # no figure of the range is written: its near end is inside the mirror box
        raise ValueError(f"--near-mm {args.near_mm:g} lies inside the mirror box (its glasses reach Z = "
                         f"{front:.1f} mm): no point there is seen through the mirrors")
    d = design_mirrors(rig, margin_mm=args.margin_mm, near_mm=args.near_mm, far_mm=args.far_mm,
                       search=not args.no_search)
    tol = tolerance_analysis(d.rig, args.near_mm, args.far_mm) if args.tolerance else None
    # the designed rig's file first: a design outside the rig bounds (e.g. a mirror metres long) is refused
    # before anything is printed or written
    rig_text = None if rig_out is None else dumps_rig(d.rig, "json" if rig_out.suffix.lower() == ".json" else "toml")
    sized, too_small = _sized_words(rig)
    print(format_design(d, sized))
    if tol is not None:
        print(format_tolerance(tol, args.near_mm, args.far_mm))
    with output_batch():
        if out is not None:
            data = design_to_dict(d)
            if tol is not None:
                data["tolerance"] = tolerance_to_dict(tol)
            write_atomic(out, json.dumps(data, indent=2) + "\n" if out.suffix.lower() == ".json" else dumps_toml(data))
        if rig_text is not None:
            write_atomic(rig_out, rig_text)
    overlaps = d.working_range is None or d.working_range.far_mm >= d.working_range.overlap_start_mm
    return 0 if d.ok and overlaps and not too_small else 1


def _sized_words(rig) -> tuple[str, bool]:
    """(a line on the rig file's own mirror sizes when it gives any, the design replacing them: what they lose of
    each view's image (:func:`psvs.optics.obstruction.sized_shares`), BLOCKED beyond half, '' without sizes;
    whether they are BLOCKED)."""
    if not finite_solids(rig):
        return "", False
    shares = sized_shares(rig)
    worst = max(shares.values())
    if worst == 0.0:
        return "The rig file's mirror sizes: clear", False
    too_small = worst > MAX_BLOCKED_SHARE
    verdict = "BLOCKED: too small for the camera's field" if too_small else "vignetted"
    return f"The rig file's mirror sizes: {verdict} ({share_words(shares)})", too_small
