"""The seat of each mirror: three contact points on its back, a fixed pivot and two fine-pitch screws.

Each mirror (and the M1 plate) rests on three contacts on the back of its glass; a spring holds the glass
against them. In the mirror's own coordinates (``s``: in-plane horizontal axis, ``t``: +Y, both from the
mirror's anchor, :class:`psvs.optics.rig.MirrorExtent`), seen from behind::

        t ^
          |   V o                      P  pivot (a fixed ball)
          |                            H  screw beside P along s: turns the mirror about the vertical
          |   P o-----------o H           line P-V, i.e. tilt a (MirrorError.tilt_rad[0])
          +----------------------> s   V  screw beside P along t: turns it about the line P-H (along s),
                                          i.e. tilt b (MirrorError.tilt_rad[1])

The contacts sit at the corners of the mirror's rectangle moved in by ``inset`` of its width and height
(the pivot at (s_min, t_min)), on the glass's back face: ``back_offset_mm`` behind the reflecting face (the
plate's thickness for M1, the glass's for a front-surface mirror). Each screw's axis is the designed
mirror's normal (fixed in the mirror box); turning it **clockwise seen from behind** (a right-hand thread
advancing away from the hand) pushes its contact by ``pitch_mm`` per turn toward the light, i.e. along the
mirror's normal (which faces the light, :class:`psvs.optics.surfaces.Plane`).

Small angles (:func:`screw_rates`): a contact moved by delta changes the plane's normal offset by a linear
field h(s, t) = alpha + beta s + gamma t through the three contacts. A tilt a about +Y through the anchor
is h = sigma a s, a tilt b about s is h = -sigma b t, with sigma = +Y . (s x n) = +-1 (the mirror's
handedness: +1 for M1 and M3, -1 for M2 and M4); alpha is the shift along the normal at the anchor. With the
rectangle layout this is |rad/turn| = pitch / lever arm (|s_H - s_P| for H, |t_V - t_P| for V), and a shift
per turn of pitch times the anchor's barycentric weight.

Exact (:func:`apply_turns`): the contacts are moved along the screw axes, the glass's back plane is put
through them, and the plane is written back as the rig's (tilt a, tilt b, shift) about the anchor. The
mirror box's turn (``box_rotation_rad``) turns seats and mirrors together, so turns act in the box's frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs._validate import check_finite
from psvs.optics.mirrors import mirror_planes
from psvs.optics.rig import MIRROR_NAMES, MirrorError, MirrorExtent, Rig

#: The two screws of each seat, in the order of their turns: H trims tilt a, V trims tilt b.
SCREWS = ("H", "V")
#: M3 x 0.5: the fine-pitch screw the issue names (mm of travel per turn).
DEFAULT_PITCH_MM = 0.5
#: The screw pitches a seat takes, mm per turn: from a differential adjuster's 0.01 (finer is not a screw a
#: hand turns) to a coarse M30's 5.
PITCH_RANGE_MM = (0.01, 5.0)
#: Glass of a front-surface mirror (mm): where its back, and so the contacts, sit behind the coating.
DEFAULT_GLASS_MM = 3.0
#: Contacts moved in from the mirror's corners by this share of its width and height.
DEFAULT_INSET = 0.1
#: The M1 plate is this much taller than its light footprint above and below (mm): the left view passes
#: through the plate, so its contacts and carrier sit in these borders, outside the light.
DEFAULT_M1_BORDER_MM = 28.0


def check_pitch(pitch_mm: float, name: str = "pitch_mm") -> None:
    """ValueError naming ``name`` unless ``pitch_mm`` lies in :data:`PITCH_RANGE_MM`."""
    lo, hi = PITCH_RANGE_MM
    number = isinstance(pitch_mm, (int, float)) and not isinstance(pitch_mm, bool)
    if not (number and math.isfinite(pitch_mm) and lo <= pitch_mm <= hi):
        raise ValueError(f"{name} must be a screw pitch of {lo:g}-{hi:g} mm per turn, got {pitch_mm!r}")


@dataclass(frozen=True)
class Seat:
    """One mirror's three contacts, in the designed mirror's (s, t) coordinates about its anchor, mm.

    ``pivot_st_mm``, ``h_st_mm``, ``v_st_mm``: (s, t) of the pivot and of screws H and V, mm;
    ``back_offset_mm``: the glass's back face (the contacts' plane) behind the reflecting face, mm;
    ``pitch_mm``: a screw's travel per turn, mm (:data:`PITCH_RANGE_MM`)."""

    mirror: str
    pivot_st_mm: tuple[float, float]
    h_st_mm: tuple[float, float]
    v_st_mm: tuple[float, float]
    back_offset_mm: float
    pitch_mm: float = DEFAULT_PITCH_MM

    def __post_init__(self):
        if self.mirror not in MIRROR_NAMES:
            raise ValueError(f"mirror must be one of {', '.join(MIRROR_NAMES)}, got {self.mirror!r}")
        check_pitch(self.pitch_mm)
        check_finite(self.back_offset_mm, "back_offset_mm")
        pts = self.contacts_st_mm
        area = _cross2(pts[1] - pts[0], pts[2] - pts[0])
        if not np.all(np.isfinite(pts)) or abs(area) < 1e-6:
            raise ValueError(f"{self.mirror}'s three contacts must be finite and not on one line, got {pts.tolist()}")

    @property
    def contacts_st_mm(self) -> np.ndarray:
        """(3, 2) mm: (s, t) of the pivot, screw H and screw V."""
        return np.array([self.pivot_st_mm, self.h_st_mm, self.v_st_mm], dtype=float)

    @property
    def levers_mm(self) -> tuple[float, float]:
        """Lever arms, mm: H's distance from the line P-V, V's distance from the line P-H."""
        p, h, v = self.contacts_st_mm
        area = abs(_cross2(h - p, v - p))
        return area / float(np.linalg.norm(v - p)), area / float(np.linalg.norm(h - p))


def _cross2(a: np.ndarray, b: np.ndarray) -> float:
    """z of the cross product of two 2-vectors (twice the signed area of their triangle)."""
    return float(a[0] * b[1] - a[1] * b[0])


def seats_for(rig: Rig, *, pitch_mm: float = DEFAULT_PITCH_MM, inset: float = DEFAULT_INSET,
              glass_mm: float = DEFAULT_GLASS_MM, m1_border_mm: float = DEFAULT_M1_BORDER_MM) -> dict[str, Seat]:
    """The seats of the four mirrors (keys ``m1`` .. ``m4``), placed on each mirror's designed rectangle.

    The rectangle is the rig's mirror extent; a rig without one (an unbounded plane) is sized first by
    :func:`psvs.optics.design.design_mirrors`. ``inset`` (0 <= inset < 0.5): the contacts' distance from
    the corners as a share of the width and height; ``glass_mm``: a front-surface mirror's glass, mm (M1's
    back is the rig's plate thickness behind its coated face). ``m1_border_mm`` > 0: the M1 plate is that
    much taller than its rectangle above and below, and its contacts sit in the middle of those borders
    (the left view passes through the plate; contacts inside its rectangle would shade it); 0: inset like
    the others."""
    check_pitch(pitch_mm)
    if not (math.isfinite(inset) and 0 <= inset < 0.5):
        raise ValueError(f"inset must be in [0, 0.5), got {inset!r}")
    if not (math.isfinite(glass_mm) and glass_mm >= 0):
        raise ValueError(f"glass_mm must be a finite thickness >= 0 mm, got {glass_mm!r}")
    if not (math.isfinite(m1_border_mm) and m1_border_mm >= 0):
        raise ValueError(f"m1_border_mm must be a finite width >= 0 mm, got {m1_border_mm!r}")
    extents = {n: rig.mirrors.extent(n) for n in MIRROR_NAMES}
    if any(e is None for e in extents.values()):
        from psvs.optics.design import design_mirrors
        sized = design_mirrors(rig, search=False).rig
        extents = {n: extents[n] or sized.mirrors.extent(n) for n in MIRROR_NAMES}
    out = {n: _seat(n, extents[n], pitch_mm, inset, glass_mm) for n in MIRROR_NAMES[1:]}
    return {"m1": _seat("m1", extents["m1"], pitch_mm, inset, rig.mirrors.plate_thickness_mm, m1_border_mm), **out}


def _seat(name: str, ext: MirrorExtent, pitch_mm: float, inset: float, back_mm: float,
          border_mm: float = 0.0) -> Seat:
    (s0, s1), (t0, t1) = ext.along_mm, ext.height_mm
    ds, dt = inset * (s1 - s0), inset * (t1 - t0)
    lo_s, hi_s, lo_t, hi_t = s0 + ds, s1 - ds, t0 + dt, t1 - dt
    if border_mm > 0:                     # in the middle of the borders above and below the light
        lo_t, hi_t = t0 - border_mm / 2, t1 + border_mm / 2
    return Seat(name, (lo_s, lo_t), (hi_s, lo_t), (lo_s, hi_t), back_mm, pitch_mm)


def _designed_planes(rig: Rig) -> dict:
    """The designed planes in the mirror box's frame (no pose error, no box turn)."""
    return mirror_planes(rig.designed_mirrors())


def handedness(rig: Rig, mirror: str) -> float:
    """sigma = +Y . (s x n) of the designed mirror (+1 or -1): the sign linking a turn about +Y (tilt a)
    or about s (tilt b) to the way the plane moves along its normal."""
    p = _designed_planes(rig)[mirror]
    return float(np.sign(np.cross(p.s_axis, p.normal)[1]))


@dataclass(frozen=True)
class ScrewRate:
    """What one clockwise turn of one screw does (small angles): ``tilt_rad_per_turn`` = (da, db), rad;
    ``shift_mm_per_turn``: the shift along the normal at the anchor, mm."""

    mirror: str
    screw: str
    tilt_rad_per_turn: tuple[float, float]
    shift_mm_per_turn: float


def screw_rates(seat: Seat, sigma: float) -> dict[str, ScrewRate]:
    """Small-angle rates of the seat's screws H and V (see the module's notes); ``sigma`` from
    :func:`handedness`. Returns ``{"H": ScrewRate, "V": ScrewRate}``."""
    st = seat.contacts_st_mm
    A = np.column_stack([np.ones(3), st])            # h = alpha + beta s + gamma t at each contact
    out = {}
    for k, screw in enumerate(SCREWS):
        delta = np.zeros(3)
        delta[k + 1] = seat.pitch_mm
        alpha, beta, gamma = np.linalg.solve(A, delta)
        out[screw] = ScrewRate(seat.mirror, screw, (float(beta / sigma), float(-gamma / sigma)), float(alpha))
    return out


def apply_turns(rig: Rig, seats: dict[str, Seat], turns: dict[str, tuple[float, float]]) -> Rig:
    """The build after its screws are turned (exact): ``turns[mirror] = (turns of H, turns of V)``,
    clockwise seen from behind > 0. Returns the rig with the turned mirrors' new (tilt, shift) errors; the
    box's turn, the lens and the mirror extents stay."""
    designed = _designed_planes(rig)
    unboxed = mirror_planes(rig.replace(box_rotation_rad=(0.0, 0.0, 0.0)))
    errors = {}
    for name, (t_h, t_v) in turns.items():
        if name not in seats:
            raise ValueError(f"no seat for mirror {name!r} (seats: {', '.join(seats)})")
        if t_h == 0 and t_v == 0:
            continue
        seat, d, now = seats[name], designed[name], unboxed[name]
        back = seat.back_offset_mm
        q = (d.point + seat.contacts_st_mm[:, :1] * d.s_axis + seat.contacts_st_mm[:, 1:] * d.t_axis
             - back * d.normal)                                         # (3, 3) contacts as designed
        now_back = now.point - back * now.normal
        lam = (now_back - q) @ now.normal / float(d.normal @ now.normal)  # along each screw's axis to the glass
        tips = q + (lam + seat.pitch_mm * np.array([0.0, t_h, t_v]))[:, None] * d.normal
        n = np.cross(tips[1] - tips[0], tips[2] - tips[0])
        n /= np.linalg.norm(n) * np.sign(n @ now.normal)
        errors[name] = plane_to_error(d, tips[0] + back * n, n)
    return rig.with_errors(errors)


def plane_to_error(designed, point_mm: np.ndarray, normal: np.ndarray) -> MirrorError:
    """The (tilt a, tilt b, shift) that put a designed :class:`~psvs.optics.surfaces.Plane` onto the plane
    through ``point_mm`` (3,) with unit ``normal`` (3,) facing the light (the inverse of the rig's tilt: a
    turn by a about +Y, then by b about the turned s axis, about the anchor, then a shift along the normal)."""
    k = np.cross(designed.s_axis, designed.normal)       # +-Y: unchanged by the turn about +Y
    sb = float(np.clip(normal @ k, -1.0, 1.0))
    b = math.asin(sb)
    n_a = (normal - sb * k) / math.cos(b)
    a = math.atan2(float(np.cross(designed.normal, n_a)[1]), float(designed.normal @ n_a))
    shift = float((point_mm - designed.point) @ normal)
    return MirrorError((a, b), shift)
