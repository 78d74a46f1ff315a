"""``psvs design``: size the four mirrors for a rig, check the layout, print and write the mirror table."""
from __future__ import annotations

import json
import math

from psvs.cli.common import add_rig_argument, check_output_path, rig_from_args
from psvs.io.atomic import write_atomic
from psvs.io.tomlfile import dumps_toml
from psvs.io.params import rig_to_dict, save_rig
from psvs.optics.design import MirrorDesign, design_mirrors


def add_parser(sub) -> None:
    p = sub.add_parser("design", help="size and check the four mirrors (eqs. 1-8 and more)",
                       description="Size all four mirrors so the rig's field equals the camera's, check that no "
                                   "mirror or the M1 plate blocks a light path, and print the mirror table. "
                                   "Exit status 1 when the layout is blocked, 2 on bad input.")
    add_rig_argument(p)
    p.add_argument("--near-mm", type=float, default=400.0, help="near end of the working range (default 400)")
    p.add_argument("--far-mm", type=float, default=1200.0, help="far end of the working range (default 1200)")
    p.add_argument("--margin-mm", type=float, default=0.0,
                   help="extra border on every mirror side, e.g. half the lens entrance pupil (default 0)")
    p.add_argument("--no-search", action="store_true", help="skip the search for clear M1/M2 positions")
    p.add_argument("-o", "--output", metavar="TABLE.json|.toml", help="write the mirror table here")
    p.add_argument("--rig-out", metavar="RIG.toml|.json", help="write the rig with the designed mirror extents")
    p.set_defaults(run=run)


def design_to_dict(d: MirrorDesign) -> dict:
    """The mirror table and checks as plain data (no None: TOML has no null)."""
    out = {"mirrors": [], "checks": {"ok": d.ok, "problems": d.problems}}
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
    if d.working_range is not None:
        wr = d.working_range
        out["working_range"] = {
            "near_mm": wr.near_mm, "far_mm": wr.far_mm, "disparity_px": list(wr.disparity_px),
            "depth_per_px_mm": list(wr.depth_per_px_mm), "overlap_start_mm": wr.overlap_start_mm}
    out["rig"] = rig_to_dict(d.rig)
    return out


def format_design(d: MirrorDesign) -> str:
    """A readable mirror table with the checks."""
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
    lines.append("Layout: clear" if d.ok else "Layout: BLOCKED")
    lines += [f"  - {p}" for p in d.problems]
    if d.m2_window_mm is not None:
        lines.append(f"  M2 clears both paths for m2_axis_distance_mm in [{d.m2_window_mm[0]:.2f}, "
                     f"{d.m2_window_mm[1]:.2f}] mm")
    if d.suggestion_mm is not None:
        lines.append(f"  Suggestion: m1_axis_distance_mm = {d.suggestion_mm[0]:.2f}, "
                     f"m2_axis_distance_mm = {d.suggestion_mm[1]:.2f}")
    if d.working_range is not None:
        wr = d.working_range
        lines += ["", f"Working range {wr.near_mm:g}-{wr.far_mm:g} mm: disparity {wr.disparity_px[0]:.1f}-"
                      f"{wr.disparity_px[1]:.1f} px; 1 px of disparity = {wr.depth_per_px_mm[0]:.2f} mm of depth "
                      f"at the near end, {wr.depth_per_px_mm[1]:.2f} mm at the far end; the views overlap "
                      f"from {wr.overlap_start_mm:.0f} mm"]
        if wr.near_mm < wr.overlap_start_mm:
            lines.append(f"  warning: the working range starts before the views overlap ({wr.overlap_start_mm:.0f} mm)")
    return "\n".join(lines)


def run(args) -> int:
    out = check_output_path(args.output, (".json", ".toml"))
    rig_out = check_output_path(args.rig_out, (".json", ".toml"))
    rig = rig_from_args(args)
    d = design_mirrors(rig, margin_mm=args.margin_mm, near_mm=args.near_mm, far_mm=args.far_mm,
                       search=not args.no_search)
    print(format_design(d))
    if out is not None:
        data = design_to_dict(d)
        write_atomic(out, json.dumps(data, indent=2) + "\n" if out.suffix.lower() == ".json" else dumps_toml(data))
    if rig_out is not None:
        save_rig(d.rig, rig_out)
    return 0 if d.ok else 1
