"""The alignment guide as a builder reads it, shared by ``psvs adjust`` / ``psvs calibrate --adjust`` and the
web page's Alignment panel: the check that a calibrated build and a design are one mirror box, the turns as
text ("3/16 turn clockwise"), the guide as printed lines and as plain data (JSON), and the twins' row-offset
maps before and after the turns (:func:`row_offset_maps`)."""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from psvs.evidence import MAX_FOCAL_CHANGE
from psvs.mount.guide import (
    NULL_PX_PER_TURN,
    REFERENCE_PITCH_MM,
    AlignmentGuide,
    designed_twin,
    twin_rows_px,
    working_points,
)
from psvs.mount.seats import Seat, apply_turns
from psvs.optics.mirrors import virtual_baseline_mm
from psvs.optics.project import project_points
from psvs.optics.rig import MIRROR_NAMES, MirrorError, Rig

TILTS = {"a": "tilt a (about the vertical)", "b": "tilt b (out of vertical)"}
#: Design values a calibrated build must share with the rig it was calibrated from (the same mirror box):
#: within 5 % or 1 deg. The baseline is judged by what it does, the distance of the virtual cameras
#: (:func:`baseline_spread_mm`): calibration may carry a change of it in the baseline or in the mirrors' shifts.
DESIGN_FIELDS = ("m1_axis_distance_mm", "m2_axis_distance_mm", "angle_rad")
DESIGN_REL_TOL, DESIGN_ANGLE_TOL_RAD = 0.05, math.radians(1.0)
#: What a printed mount's seats hold each glass to: glued within 0.2 deg about both axes and 0.5 mm along its
#: normal (the default tolerances of docs/tolerancing.md, psvs/rigs/tolerances_default.toml).
SEAT_TILT_RAD, SEAT_SHIFT_MM = math.radians(0.2), 0.5
#: mm: what a calibration's own error adds to the virtual cameras' distance (0.06 mm 3-D errors, docs/calibration.md).
CALIBRATION_BASELINE_MM = 0.1


def baseline_spread_mm(nominal: Rig, tilt_rad: float = SEAT_TILT_RAD, shift_mm: float = SEAT_SHIFT_MM) -> float:
    """The most |O1 O2| of a build of ``nominal`` can differ from the design's with every glass anywhere in its
    seat (tilted up to ``tilt_rad`` about both axes, moved up to ``shift_mm`` along its normal), mm: the worst
    case of the linearised change, the sum over the 12 pose errors of |d|O1 O2| / d error| times its tolerance
    (4.4 mm for the shipped 100 mm designs). The box's turn moves both virtual cameras together: it adds none."""
    nominal = nominal.with_errors({n: MirrorError() for n in MIRROR_NAMES})   # the design itself, even of a build
    b0 = virtual_baseline_mm(nominal)
    total = 0.0
    for name in MIRROR_NAMES:
        for error, tol in ((MirrorError((1e-5, 0.0), 0.0), tilt_rad), (MirrorError((0.0, 1e-5), 0.0), tilt_rad),
                           (MirrorError((0.0, 0.0), 1e-4), shift_mm)):
            step = 1e-4 if error.shift_mm else 1e-5
            total += abs(virtual_baseline_mm(nominal.with_errors({name: error})) - b0) / step * tol
    return total


def check_same_design(built: Rig, nominal: Rig, design: str = "--rig") -> None:
    """ValueError unless the calibrated build and the design (called ``design`` in the message) share the
    mirror box's layout (:data:`DESIGN_FIELDS`), the camera (its size, and its focal length within
    :data:`psvs.evidence.MAX_FOCAL_CHANGE`) and its virtual cameras' distance lies within what its seats allow
    (:func:`baseline_spread_mm`, plus :data:`CALIBRATION_BASELINE_MM`)."""
    f_built, f_design = built.camera.focal_length_mm, nominal.camera.focal_length_mm
    if (tuple(built.camera.image_size_px) != tuple(nominal.camera.image_size_px)
            or abs(f_built / f_design - 1.0) > MAX_FOCAL_CHANGE):
        raise ValueError(f"the calibrated rig and {design} are not one design: its camera is "
                         f"{built.camera.image_size_px[0]}x{built.camera.image_size_px[1]} px with f {f_built:g} mm, "
                         f"the design's {nominal.camera.image_size_px[0]}x{nominal.camera.image_size_px[1]} px with "
                         f"f {f_design:g} mm (a stock lens: within {MAX_FOCAL_CHANGE:.0%}; give the design the build "
                         "was calibrated from)")
    b_built, b_design = virtual_baseline_mm(built), virtual_baseline_mm(nominal)
    limit = baseline_spread_mm(nominal) + CALIBRATION_BASELINE_MM
    if abs(b_built - b_design) > limit:
        raise ValueError(f"the calibrated rig and {design} are not one design: its virtual cameras stand "
                         f"{b_built:.2f} mm apart, the design's {b_design:.2f} mm, beyond the {limit:.2f} mm its "
                         f"glass seated within {math.degrees(SEAT_TILT_RAD):g} deg and {SEAT_SHIFT_MM:g} mm can make "
                         "(give the design the build was calibrated from)")
    for name in DESIGN_FIELDS:
        a, b = getattr(built.mirrors, name), getattr(nominal.mirrors, name)
        close = abs(a - b) <= DESIGN_ANGLE_TOL_RAD if name == "angle_rad" else abs(a - b) <= DESIGN_REL_TOL * abs(b)
        if not close:
            unit = "deg" if name.endswith("rad") else "mm"
            conv = math.degrees if unit == "deg" else float
            raise ValueError(f"the calibrated rig and {design} are not one design: {name.replace('_rad', '')} "
                             f"{conv(a):g} vs {conv(b):g} {unit} (give the design the build was calibrated from)")


def turns_text(turns: float) -> str:
    """'1 3/16 turn', '1/4 turn', '0' for a multiple of 1/16 turn (sign dropped)."""
    f = Fraction(abs(turns)).limit_denominator(16)
    whole, rest = divmod(f, 1)
    if f == 0:
        return "0"
    parts = ([str(whole)] if whole else []) + ([f"{rest.numerator}/{rest.denominator}"] if rest else [])
    return " ".join(parts) + (" turns" if f > 1 else " turn")


def turn_instruction(turns: float, direction: str) -> str:
    """What to do with one screw: 'leave', or e.g. '3/16 turn clockwise'."""
    return "leave" if turns == 0 else f"{turns_text(turns)} {direction}"


def format_guide(g: AlignmentGuide) -> str:
    """The guide as a table a builder follows at the bench."""
    lines = [f"alignment guide: {g.n_points} field points over {g.near_mm:g}-{g.far_mm:g} mm, screws of "
             f"{g.pitch_mm:g} mm pitch (clockwise = seen from behind the mirror)",
             f"twins' row offset before: largest {g.before_px[0]:.2f} px, RMS {g.before_px[1]:.2f} px",
             f"{'mirror':6} {'screw':5} {'trims':29} {'deg/turn':>9}  turn"]
    for t in g.turns:
        how = turn_instruction(t.turns, t.direction)
        lines.append(f"{t.mirror.upper():6} {t.screw:5} {TILTS[t.tilt]:29} {math.degrees(t.rad_per_turn):9.3f}  {how}")
    lines.append(f"twins' row offset after the turns (predicted): largest {g.after_px[0]:.2f} px, "
                 f"RMS {g.after_px[1]:.2f} px ({g.after_unquantised_px[0]:.2f} px with turns not rounded to 1/16)")
    if g.lost_after:
        lines.append(f"  over {g.n_points - g.lost_after} points: {g.lost_after} of the {g.n_points} leave a view "
                     "after the turns (a turned mirror's edge moves into the field; psvs design --margin-mm "
                     "sizes the mirrors with room for it)")
    lines += null_space_lines(g)
    return "\n".join(lines)


def guide_or_refusal(g: AlignmentGuide) -> str:
    """:func:`format_guide` when the turns align the build, else one line saying why they do not (what
    ``calibrate --adjust`` and ``refit --adjust`` print beside the rig they wrote, which stands either way)."""
    return format_guide(g) if g.aligned else f"alignment guide: {g.refusal()}"


def null_space_lines(g: AlignmentGuide) -> list[str]:
    """The guide's note on the turn combinations the rows cannot tell apart (none: an empty list)."""
    if not g.null_space:
        return []
    unseen = NULL_PX_PER_TURN * g.pitch_mm / REFERENCE_PITCH_MM
    lines = [f"{len(g.null_space)} combination(s) of turns move no twin off its partner's row (< {unseen:.2g} px "
             "per turn: they move both twins alike, or along their rows), so the rows cannot tell them "
             "apart; the turns start from the smallest that fit, and rounding them to 1/16 may move along:"]
    names = [f"{t.mirror.upper()} {t.screw}" for t in g.turns]
    for v in g.null_space:
        big = sorted(range(len(v)), key=lambda k: -abs(v[k]))[:3]
        lines.append("  " + ", ".join(f"{v[k]:+.2f} {names[k]}" for k in big) + " ...")
    return lines


def guide_to_dict(g: AlignmentGuide) -> dict:
    """The guide as plain data (JSON)."""
    return {
        "near_mm": g.near_mm, "far_mm": g.far_mm, "points": g.n_points, "pitch_mm": g.pitch_mm,
        "row_offset_before_px": {"max": g.before_px[0], "rms": g.before_px[1]},
        "row_offset_after_px": {"max": g.after_px[0], "rms": g.after_px[1]},
        "row_offset_after_unrounded_px": {"max": g.after_unquantised_px[0], "rms": g.after_unquantised_px[1]},
        "points_lost_after": g.lost_after,
        "turns": [{"mirror": t.mirror.upper(), "screw": t.screw, "tilt": t.tilt, "turns": t.turns,
                   "direction": t.direction, "deg_per_turn": math.degrees(t.rad_per_turn),
                   "shift_mm_per_turn": t.shift_mm_per_turn} for t in g.turns],
        "null_space": [list(v) for v in g.null_space],
        "singular_px_per_turn": list(g.singular_px),
    }


def _finite_or_none(a: np.ndarray) -> list[float | None]:
    return [float(x) if np.isfinite(x) else None for x in a]


def row_offset_maps(built: Rig, seats: dict[str, Seat], g: AlignmentGuide) -> dict:
    """The twins' row offset over the guide's field points, before the turns (``built``) and after them
    (:func:`~psvs.mount.seats.apply_turns` of ``g``'s turns on ``built``), as plain data (JSON).

    The points are :func:`~psvs.mount.guide.working_points` (the left view's 11 x 9 pixel grid at 3
    depths, where both views see them); ``u_px``, ``v_px`` are where each lands in the left view of the
    build's design (the grid pixels, the same before and after, so the maps compare point for point). The
    offset is :func:`~psvs.mount.guide.row_offsets_px`, px, None where a view misses the point; ``weighed``
    marks the points the guide's numbers are over (``g.weighed``), so the largest |offset| of the weighed
    points after the turns is ``g.after_px[0]``.

    Returns
    -------
    dict
        ``image_size_px`` [W, H]; ``before`` and ``after``: one entry per depth, near to far, each
        ``{"z_mm", "u_px", "v_px", "offset_px", "weighed"}`` (lists of one length).
    """
    pts = working_points(built, g.near_mm, g.far_mm)
    design = designed_twin(built)
    uv, _ = project_points(pts, design, "left")
    base = twin_rows_px(design, pts)
    offsets = {"before": twin_rows_px(built, pts) - base,
               "after": twin_rows_px(apply_turns(built, seats, g.turns_by_mirror), pts) - base}
    weighed = np.zeros(len(pts), bool)
    weighed[list(g.weighed)] = True
    depths = np.round(pts[:, 2], 6)
    out = {"image_size_px": [int(s) for s in built.camera.image_size_px]}
    for when, r in offsets.items():
        out[when] = [{"z_mm": float(z), "u_px": _finite_or_none(uv[depths == z, 0]),
                      "v_px": _finite_or_none(uv[depths == z, 1]), "offset_px": _finite_or_none(r[depths == z]),
                      "weighed": [bool(w) for w in weighed[depths == z]]} for z in np.unique(depths)]
    return out
