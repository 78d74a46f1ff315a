"""What ``psvs mount`` writes besides the solid: the bill of materials (``bom.csv``) and ``mount.toml``
(the parameters, each mirror's glass and seat: where its contacts are, which screw turns which tilt and by
how much per turn), and the reader that gives the seats back to ``psvs adjust --mount`` and
``psvs calibrate --adjust DIR``."""
from __future__ import annotations

import csv
import io
import math
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np

from psvs.io.tomlfile import dumps_toml, load_toml, parse_text
from psvs.mount.layout import (
    CLAMP_SLIT_MM,
    CLIP_BORDER_MM,
    SCREW_CLEARANCE_MM,
    SPRING_REACH_MM,
    MountLayout,
    MountParams,
)
from psvs.mount.seats import SCREWS, Seat, handedness, screw_rates
from psvs.optics.mirrors import mirror_planes
from psvs.optics.rig import MIRROR_NAMES, Rig

#: PLA's density, g/cm^3, for the printed part's mass in the bill of materials.
PLA_G_PER_CM3 = 1.24
#: The tilt each screw trims (docs/mount.md).
TRIMS = {"H": "tilt a (about the vertical)", "V": "tilt b (out of vertical)"}
BOM_COLUMNS = ("item", "qty", "part", "size", "notes")
#: A screw's thread length: its insert's plate, the standoff, and 5 mm to turn it by (rounded up to a stock length).
STOCK_LENGTHS_MM = (6, 8, 10, 12, 16, 20, 25, 30, 35, 40, 45, 50, 60, 70, 80)


def _stock(length_mm: float) -> int:
    return next((n for n in STOCK_LENGTHS_MM if n >= length_mm), int(math.ceil(length_mm)))


def bom_rows(layout: MountLayout) -> list[dict]:
    """The bill of materials: the glass, the printed mount, screws, inserts, springs, as rows of
    :data:`BOM_COLUMNS`."""
    p, m = layout.params, layout.rig.mirrors
    rows = []
    for name in MIRROR_NAMES:
        w, h = layout.glass[name].size_mm
        if name == "m1":
            t = f"{round(100 * m.split_ratio)}/{round(100 * (1 - m.split_ratio))}"
            rows.append(("M1", 1, f"beam-splitter plate {t} (R/T), n = {m.refractive_index:g}",
                         f"{w:.2f} x {h:.2f} x {m.plate_thickness_mm:.2f} mm",
                         "coated face toward the camera; light passes the middle, the contacts sit in the "
                         f"{p.m1_border_mm:g} mm borders above and below"))
        else:
            rows.append((name.upper(), 1, "front-surface mirror", f"{w:.2f} x {h:.2f} x {p.glass_mm:.2f} mm",
                         f"coating toward the light; the springs press on the {CLIP_BORDER_MM:g} mm borders above "
                         "and below"))
    n_mirrors = len(MIRROR_NAMES)
    screw = _stock(p.plate_mm + p.standoff_mm + 1.0)
    rows += [("mount", 1, "printed mount (mount.stl)", f"{layout.volume_mm3 / 1000:.1f} cm^3",
              f"{layout.volume_mm3 / 1000 * PLA_G_PER_CM3:.0f} g in PLA at 100 % infill; walls >= {p.wall_mm:g} mm"),
             ("screw", 2 * n_mirrors, f"M3 x {p.pitch_mm:g} set screw (grub screw), nylon tip, nylon-patch lock",
              f"M3 x {screw} mm", "H and V of each seat: the tip carries the glass, turned from behind with a "
              "1.5 mm hex key; headless, so nothing stands in the light behind the carrier (checked: "
              "4 mm of screw behind it)"),
             ("insert", 4 * n_mirrors, f"M3 heat-set insert ({2 * n_mirrors} of them M3 x {p.pitch_mm:g} for the "
              "set screws)", "Ø4.0 x 4 mm",
              "melted into each seat's two Ø4.0 mm holes and each spring's hole in the floor and lid (no "
              "clearance added: the insert needs the grip)"),
             ("leaf spring", 2 * n_mirrors, "leaf spring (e.g. 0.2 mm spring steel, 8 mm wide)", "~2 N",
              f"two per mirror, screwed into the floor's and the lid's insert {SPRING_REACH_MM:g} mm in front "
              "of the glass's middle, pressing its border (outside the light) onto the three contacts"),
             ("spring screw", 2 * n_mirrors, "M3 button head screw", "M3 x 6 mm", "one per leaf spring")]
    if p.interface == "clamp":
        rows.append(("clamp screw", 1, "M3 socket head screw + nut",
                     f"M3 x {_stock(2 * (p.lens_diameter_mm / 2 + p.plate_mm) + 3)} mm",
                     f"closes the lens clamp's {CLAMP_SLIT_MM:g} mm split on the Ø{p.lens_diameter_mm:g} mm barrel"))
    else:
        rows.append(("camera screw", 4, "M3 socket head screw", f"M3 x {_stock(p.plate_mm + 4)} mm",
                     f"{p.interface.upper()}-mount flange plate to the camera's front face "
                     f"(holes Ø{SCREW_CLEARANCE_MM:g} mm on a {p.hole_square_mm:g} mm square)"))
    return [dict(zip(BOM_COLUMNS, r, strict=True)) for r in rows]


def bom_csv(layout: MountLayout) -> str:
    """The bill of materials as CSV text (:data:`BOM_COLUMNS`, one row per part)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, BOM_COLUMNS, lineterminator="\n")
    w.writeheader()
    w.writerows(bom_rows(layout))
    return buf.getvalue()


def mount_dict(layout: MountLayout, checks: dict) -> dict:
    """``mount.toml``'s content: parameters, each mirror's glass and seat (contacts in the mirror's (s, t)
    and in the rig's frame, mm; per screw the tilt it trims and the degrees and shift per clockwise turn),
    the volume and the checks."""
    planes = mirror_planes(layout.rig)
    seats = {}
    for name in MIRROR_NAMES:
        seat, plane, ext = layout.seats[name], planes[name], layout.glass[name]
        rates = screw_rates(seat, handedness(layout.rig, name))
        xyz = [plane.point + s * plane.s_axis + t * np.array([0.0, 1.0, 0.0]) - seat.back_offset_mm * plane.normal
               for s, t in seat.contacts_st_mm]
        seats[name] = {
            "glass_along_mm": list(ext.along_mm), "glass_height_mm": list(ext.height_mm),
            "back_offset_mm": seat.back_offset_mm, "pitch_mm": seat.pitch_mm,
            "pivot_st_mm": list(seat.pivot_st_mm), "h_st_mm": list(seat.h_st_mm), "v_st_mm": list(seat.v_st_mm),
            "pivot_xyz_mm": [float(v) for v in xyz[0]], "h_xyz_mm": [float(v) for v in xyz[1]],
            "v_xyz_mm": [float(v) for v in xyz[2]],
            "screws": {s: {"trims": TRIMS[s], "tilt_deg_per_turn": math.degrees(
                rates[s].tilt_rad_per_turn[0 if s == "H" else 1]), "shift_mm_per_turn": rates[s].shift_mm_per_turn,
                "clockwise_from_behind": "pushes the glass toward the light"} for s in SCREWS}}
    return {"mount": {"params": asdict(layout.params), "floor_y_mm": layout.floor_y_mm,
                      "m1_strip_y_mm": layout.m1_strip_y_mm, "volume_mm3": layout.volume_mm3},
            "seats": seats, "checks": checks}


def mount_toml(layout: MountLayout, checks: dict) -> str:
    """mount.toml's text: the layout's parameters and seats and the ``checks`` it passed (:func:`read_mount`
    reads it back)."""
    return dumps_toml(mount_dict(layout, checks))


#: mm: how far a seat's contacts may stand off the plane of the design's glass (its back face) and still be a
#: seat of that design (a mount made for another one puts them millimetres off).
SEAT_PLANE_TOL_MM = 0.5


def read_mount(folder, design: Rig | None = None) -> tuple[MountParams, dict[str, Seat]]:
    """The parameters and seats ``psvs mount`` wrote to ``folder/mount.toml`` (ValueError naming what is
    wrong; with ``design``, also when the seats are not on its glasses: :func:`check_seats_on`)."""
    path = Path(folder) / "mount.toml"
    if not path.is_file():
        raise ValueError(f"{folder}: no mount.toml (a folder psvs mount wrote)")
    return mount_from_dict(load_toml(path, "mount file"), str(path), design)


def read_mount_text(text: str, where: str = "mount.toml", design: Rig | None = None) -> tuple[MountParams,
                                                                                               dict[str, Seat]]:
    """:func:`read_mount` on the text of a ``mount.toml`` (e.g. uploaded to the web page); errors name
    ``where``."""
    return mount_from_dict(parse_text(text, where), where, design)


def check_seats_on(data: dict, design: Rig, where: str) -> None:
    """ValueError unless every contact of every seat in a parsed ``mount.toml`` (``pivot/h/v_xyz_mm``, frame C)
    lies on ``design``'s glass: its back face, ``back_offset_mm`` behind the reflecting plane, within
    :data:`SEAT_PLANE_TOL_MM`. A mount made for another design (M1 at 16 mm for one at 22) would give turns
    for glasses it does not hold."""
    planes = mirror_planes(design)
    for name, seat in data["seats"].items():
        plane = planes[name]
        for key in ("pivot_xyz_mm", "h_xyz_mm", "v_xyz_mm"):
            at = np.asarray(seat[key], float) - plane.point
            off = float(np.dot(at, plane.normal)) + float(seat["back_offset_mm"])
            if not abs(off) <= SEAT_PLANE_TOL_MM:
                raise ValueError(f"{where}: its seats are not on this design's glasses ({name.upper()}'s "
                                 f"{key.split('_')[0]} contact stands {off:+.2f} mm off its glass's back face): a "
                                 "mount made for another design")


def mount_from_dict(data: dict, where: str, design: Rig | None = None) -> tuple[MountParams, dict[str, Seat]]:
    """The parameters and seats of a parsed ``mount.toml`` (ValueError naming ``where`` and what is wrong; with
    ``design``, also :func:`check_seats_on`)."""
    try:
        names = {f.name for f in fields(MountParams)}
        params = MountParams(**{k: v for k, v in data["mount"]["params"].items() if k in names})
        seats = {n: Seat(n, tuple(s["pivot_st_mm"]), tuple(s["h_st_mm"]), tuple(s["v_st_mm"]),
                         float(s["back_offset_mm"]), float(s["pitch_mm"])) for n, s in data["seats"].items()}
    except KeyError as exc:
        raise ValueError(f"{where}: not a mount file psvs wrote (missing {exc})") from None
    except (TypeError, AttributeError) as exc:
        raise ValueError(f"{where}: not a mount file psvs wrote ({exc})") from None
    except ValueError as exc:
        raise ValueError(f"{where}: {str(exc).splitlines()[0]}") from None
    if sorted(seats) != sorted(MIRROR_NAMES):
        raise ValueError(f"{where}: seats for {', '.join(sorted(seats))}, expected {', '.join(MIRROR_NAMES)}")
    if design is not None:
        try:
            check_seats_on(data, design, where)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"{where}: not a mount file psvs wrote (missing {exc})") from None
    return params, seats
