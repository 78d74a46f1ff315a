"""Route of the alignment guide (issue: from design to glass; docs/mount.md): a calibrated build's rig file
in, the screw turns that bring its twins onto the same rows out, as ``psvs adjust`` prints them, with the
twins' row-offset maps before and after the turns for the page's heat maps."""
from __future__ import annotations

import math

from fastapi import APIRouter

from psvs.io.params import load_rig, rig_from_text
from psvs.mount import report
from psvs.mount.files import read_mount_text
from psvs.mount.guide import alignment_guide, check_aligned
from psvs.mount.seats import DEFAULT_PITCH_MM, Seat, seats_for
from psvs.optics.rig import Rig
from psvs.rigs import SHIPPED, shipped_rig_path
from psvs.web.bodies import AdjustBody
from psvs.web.session import SessionDep

router = APIRouter(prefix="/api")


def design_rig(spec: str | None, session) -> tuple[Rig, str]:
    """The design a build was calibrated from, and what to call it: the app's rig (``spec`` None), a shipped
    rig by its name (one line without ``=`` or ``[``; never a file on the server), or a rig file's text."""
    if spec is None:
        return session.rig, session.rig_name
    name = spec.strip()
    if "\n" not in name and "=" not in name and "[" not in name:
        if name not in SHIPPED:
            raise ValueError(f"unknown rig name {name!r} (shipped: {', '.join(SHIPPED)}), or give a rig file's text")
        return load_rig(shipped_rig_path(name)), name
    return rig_from_text(spec, "design rig file"), "design rig file"


def adjust_seats(body: AdjustBody, nominal: Rig) -> dict[str, Seat]:
    """The seats of the mount.toml the body carries, or those of :func:`psvs.mount.seats.seats_for` on the
    design with the body's pitch; a pitch that contradicts the mount's seats is refused."""
    if body.mount is None:
        return seats_for(nominal, pitch_mm=DEFAULT_PITCH_MM if body.pitch_mm is None else body.pitch_mm)
    seats = read_mount_text(body.mount, "mount.toml", nominal)[1]
    pitch = seats["m1"].pitch_mm
    if body.pitch_mm is not None and abs(body.pitch_mm - pitch) > 1e-9:
        raise ValueError(f"pitch_mm {body.pitch_mm:g} mm contradicts mount.toml's seats ({pitch:g} mm): "
                         "leave it out with a mount")
    return seats


@router.post("/adjust")
def adjust(body: AdjustBody, session: SessionDep):
    """The alignment guide of the calibrated build on the design's seats (or the mount's), as
    :func:`psvs.mount.report.guide_to_dict` gives it and as ``psvs adjust`` prints it (``text``), its table
    (mirror, screw, the tilt it trims, degrees per turn, the turn: "3/16 turn clockwise" or "leave"), the
    note on what the rows cannot tell apart (``null_space_text``), and the row-offset maps before and after
    the turns (:func:`psvs.mount.report.row_offset_maps`)."""
    built = rig_from_text(body.calibrated, "calibrated rig file")
    nominal, design_name = design_rig(body.design, session)
    report.check_same_design(built, nominal, f"the design ({design_name})")
    seats = adjust_seats(body, nominal)
    g = check_aligned(alignment_guide(built, seats, body.near_mm, body.far_mm))
    table = [{"mirror": t.mirror.upper(), "screw": t.screw, "trims": report.TILTS[t.tilt],
              "deg_per_turn": math.degrees(t.rad_per_turn), "turn": report.turn_instruction(t.turns, t.direction)}
             for t in g.turns]
    return {"design": design_name, "guide": report.guide_to_dict(g), "text": report.format_guide(g).splitlines(),
            "table": table, "null_space_text": report.null_space_lines(g),
            "maps": report.row_offset_maps(built, seats, g)}


@router.get("/adjust/designs")
def adjust_designs(session: SessionDep):
    """What the Alignment panel offers as the design: the app's rig (by its name) or a shipped rig, and the
    default seats' screw pitch."""
    return {"served": session.rig_name, "shipped": list(SHIPPED), "pitch_mm": DEFAULT_PITCH_MM}
