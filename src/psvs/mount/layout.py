"""The printable mount's layout: every part as a plain prism in the rig's frame (mm), before any CAD.

The mount is a tray: a floor below the light and a lid above it (the same outline, the convex hull of
every part's footprint seen from above), joined by one **carrier** per mirror and by the camera's
interface. Each carrier is a plate parallel to its mirror, behind the glass's back face, carrying the
mirror's three contacts (:mod:`psvs.mount.seats`): a half ball (the pivot P) and two threaded holes for
the screws H and V, whose tips stand ``standoff_mm`` proud of the plate as the glass rests on them.

- M2, M3 and M4 are front-surface mirrors: their carriers are full walls from floor to lid behind the
  glass, ``margin`` wider than it on both sides.
- The left view passes *through* the M1 plate, so nothing may stand behind its light footprint: the plate
  is cut ``m1_border_mm`` taller above and below, and its carrier is two strips behind those borders only,
  one rising from the floor, one hanging from the lid, starting where the light behind the plate ends.
- The floor and lid sit beyond every traced field ray that crosses their outline (to the working range's
  far end), plus :data:`LIGHT_MARGIN_MM`; so do M1's strips.
- The camera: a **clamp** block bored for the lens barrel (split above the bore, one M3 screw across the
  split), or a **flange** plate at the camera's mount flange (C or CS), bored for the lens with four M3
  holes for the camera's front face. The barrel is a cylinder of the given diameter up to ``lens_front_mm``
  along the axis (O, the entrance pupil, at 0); the clamp holds it 2 mm behind its front.

Parts touch but never overlap, so the mount's volume is the sum of the parts' (holes and the clamp's
split taken away, the pivots' half balls added): :attr:`MountLayout.volume_mm3`, which the solid the CAD
builds must match. :func:`mount_layout` raises :class:`MountError` (naming the culprit) when a layout
cannot be built: a blocked design, a contact in the light, the lens in the glass.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

from psvs._validate import check_positive
from psvs.mount.seats import DEFAULT_GLASS_MM, DEFAULT_INSET, DEFAULT_M1_BORDER_MM, DEFAULT_PITCH_MM, Seat, seats_for
from psvs.optics.design import MirrorDesign
from psvs.optics.mirrors import mirror_planes
from psvs.optics.rig import MIRROR_NAMES, MirrorExtent, Rig

#: Free space kept between any traced ray and the floor, lid or M1's strips at least, mm (or the margin).
LIGHT_MARGIN_MM = 1.0
#: Behind each carrier, the seat's set screw (M3: 1.6 mm radius) may stand out this far as it is backed off:
#: no light may pass there either.
SCREW_KEEPOUT_MM = 4.0
SCREW_KEEPOUT_RADIUS_MM = 1.6
#: Each glass is held on its contacts by two leaf springs, one screwed into the floor and one into the lid,
#: their M3 inserts this far in front of the glass's middle; the spring's room: this wide along the glass
#: and reaching 3 mm past its insert.
SPRING_REACH_MM = 6.0
SPRING_WIDTH_MM = 8.0
#: A carrier (and the floor and lid) is at least this thick: an M3 heat-set insert (4 mm) and 1 mm more.
CARRIER_MIN_MM = 5.0
#: Hole for an M3 heat-set insert (Ø4.0 mm, 4 mm long) before the printer's clearance; the clamp's screw
#: passes a Ø3.4 mm clearance hole.
INSERT_HOLE_MM = 4.0
SCREW_CLEARANCE_MM = 3.4
INTERFACES = ("clamp", "c", "cs")
CLAMP_SLIT_MM = 1.5
#: M2, M3 and M4 are cut this much taller than their light above and below: the springs press there.
CLIP_BORDER_MM = 3.0


class MountError(ValueError):
    """A mount that cannot be built as asked; the message names the culprit."""


#: mm: the thinnest wall a printer's --wall-mm may ask (an FDM nozzle's line; a thick one is the build's to refuse).
MIN_WALL_MM = 0.4


@dataclass(frozen=True)
class MountParams:
    """What the builder chooses (mm). ``interface``: 'clamp' (a block bored for the lens barrel) or 'c' /
    'cs' (a plate at the camera's mount flange); ``lens_diameter_mm``: the barrel; ``lens_front_mm``: its
    front face along the axis from O (the entrance pupil, the rig's origin), > 0 ahead of O;
    ``flange_mm``: for 'c'/'cs', the flange plane behind O (> 0; the same plate for both: the mount's name
    goes to the bill of materials); ``hole_square_mm``: the camera's four front-face holes on a square of
    this side; ``margin_mm``: every mirror's border beyond its chief rays' footprint (``psvs design
    --margin-mm``), and the free space around the light: about half the lens's entrance pupil, since the
    traced rays are chief rays through O; ``wall_mm``: the thinnest wall the printer makes;
    ``clearance_mm``: the printer's clearance, added to every hole and fit; ``standoff_mm``: the contacts'
    height above their carrier."""

    interface: str = "clamp"
    lens_diameter_mm: float = 30.0
    lens_front_mm: float = 0.0
    flange_mm: float = 25.0
    hole_square_mm: float = 36.0
    wall_mm: float = 2.0
    clearance_mm: float = 0.3
    standoff_mm: float = 2.0
    pitch_mm: float = DEFAULT_PITCH_MM
    glass_mm: float = DEFAULT_GLASS_MM
    m1_border_mm: float = DEFAULT_M1_BORDER_MM
    margin_mm: float = 0.0

    def __post_init__(self):
        if self.interface not in INTERFACES:
            raise ValueError(f"interface must be one of {', '.join(INTERFACES)}, got {self.interface!r}")
        for name in ("lens_diameter_mm", "flange_mm", "hole_square_mm", "wall_mm", "standoff_mm", "pitch_mm",
                     "glass_mm", "m1_border_mm"):
            check_positive(getattr(self, name), name, "mm")
        if not self.wall_mm >= MIN_WALL_MM:           # (a trial: 0.01 mm was taken and printed in the BOM)
            raise ValueError(f"wall_mm (--wall-mm) is the thinnest wall the printer makes: at least {MIN_WALL_MM:g} "
                             f"mm (one 0.4 mm nozzle's line), got {self.wall_mm:g}")
        if not (math.isfinite(self.clearance_mm) and 0 <= self.clearance_mm <= 2):
            raise ValueError(f"clearance_mm must be in [0, 2] mm, got {self.clearance_mm!r}")
        if not (math.isfinite(self.margin_mm) and 0 <= self.margin_mm <= 10):
            raise ValueError(f"margin_mm must be in [0, 10] mm, got {self.margin_mm!r}")
        if not math.isfinite(self.lens_front_mm):
            raise ValueError(f"lens_front_mm must be finite, got {self.lens_front_mm!r}")

    @property
    def plate_mm(self) -> float:
        """Thickness of every carrier, the floor and the lid, mm."""
        return max(self.wall_mm, CARRIER_MIN_MM)

    @property
    def insert_radius_mm(self) -> float:
        """A heat-set insert's hole: undersized by design (the insert melts into it), no clearance added."""
        return INSERT_HOLE_MM / 2

    @property
    def light_margin_mm(self) -> float:
        """Free space kept between any field ray and the part, mm: the margin, at least 1 mm."""
        return max(LIGHT_MARGIN_MM, self.margin_mm)


@dataclass(frozen=True)
class Box:
    """A rectangular block: centre (3,), unit axes x_dir and z_dir (3,) (y = z x x), size (3,) along x, y, z."""

    name: str
    centre: tuple
    x_dir: tuple
    z_dir: tuple
    size: tuple

    @property
    def volume_mm3(self) -> float:
        return float(np.prod(self.size))

    def corners(self) -> np.ndarray:
        """(8, 3) mm."""
        x, z = np.asarray(self.x_dir, float), np.asarray(self.z_dir, float)
        y = np.cross(z, x)
        h = np.asarray(self.size, float) / 2
        signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
        return np.asarray(self.centre) + (signs * h) @ np.stack([x, y, z])


@dataclass(frozen=True)
class Slab:
    """A polygon in the XZ plane, ``outline_xz`` (n, 2) mm counter-clockwise, extruded from Y = y0 to y1."""

    name: str
    outline_xz: tuple
    y0: float
    y1: float

    @property
    def volume_mm3(self) -> float:
        p = np.asarray(self.outline_xz)
        area = 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
        return float(area * (self.y1 - self.y0))


@dataclass(frozen=True)
class Cylinder:
    """A cylinder cut from the parts: centre (3,), unit axis (3,), radius and length, mm (whole inside
    one part, so its volume is removed exactly)."""

    name: str
    centre: tuple
    axis: tuple
    radius_mm: float
    length_mm: float

    @property
    def volume_mm3(self) -> float:
        return math.pi * self.radius_mm ** 2 * self.length_mm


@dataclass(frozen=True)
class Ball:
    """A pivot: a ball of ``radius_mm`` centred on its carrier's face, half of it standing proud."""

    name: str
    centre: tuple
    radius_mm: float

    @property
    def volume_mm3(self) -> float:
        return 2.0 / 3.0 * math.pi * self.radius_mm ** 3


@dataclass(frozen=True)
class MountLayout:
    """Every part of the mount (mm, the rig's frame): ``solids`` are unioned, ``cuts`` (holes, and the
    clamp's split as a :class:`Box`) taken away; ``extra_volume_mm3`` corrects what a cut shares with
    another cut (the split with the bore); ``glass`` each mirror's glass rectangle (M1's with its borders),
    ``seats`` each mirror's contacts; ``floor_y_mm`` the floor's top (the lid's underside at minus it);
    ``keepouts``: where the bought hardware stands (each set screw behind its carrier, :class:`Cylinder`),
    not printed, but no light may pass there."""

    rig: Rig
    params: MountParams
    solids: tuple
    cuts: tuple
    balls: tuple
    glass: dict
    seats: dict
    floor_y_mm: float
    m1_strip_y_mm: float
    extra_volume_mm3: float = 0.0
    keepouts: tuple = ()

    @property
    def volume_mm3(self) -> float:
        """The mount's volume from its parts alone (they touch, never overlap), mm^3."""
        add = sum(p.volume_mm3 for p in self.solids) + sum(b.volume_mm3 for b in self.balls)
        return float(add - sum(c.volume_mm3 for c in self.cuts) + self.extra_volume_mm3)


def field_segments(rig: Rig, far_mm: float, per_side: int = 1025, interior: int = 60) -> list[np.ndarray]:
    """The design's traced field rays (:func:`psvs.optics.field.field_pixels`, denser: ``4 per_side +
    interior^2`` pixels a view) of both views, as segments: a list of (p0 (N, 3), p1 (N, 3)) mm per leg,
    camera -> each surface -> the working range's far end (Z = ``far_mm``). Blocked or missing rays dropped."""
    from psvs.optics.field import field_pixels
    from psvs.optics.mirrors import VIEWS
    from psvs.optics.trace import trace_pixels
    pixels = field_pixels(rig.camera, per_side, interior)
    out = []
    for view in VIEWS:
        hits: list = []
        rays = trace_pixels(pixels, rig, view, hits)
        ok = rays.valid
        o, d = rays.origins_mm[ok], rays.dirs[ok]
        reach = (far_mm - o[:, 2]) / d[:, 2]
        pts = [np.zeros_like(o)] + [h[ok] for _, h, _ in hits] + [o + reach[:, None] * d]
        out += [(pts[i], pts[i + 1]) for i in range(len(pts) - 1)]
    return out


def max_abs_y_over(outline_xz: np.ndarray, segments: list) -> float:
    """The largest |Y| of any segment where it passes over the convex polygon ``outline_xz`` (n, 2) in the
    XZ plane (Cyrus-Beck clipping; |Y| is largest at a clipped end), mm; 0 when none passes over it."""
    p = np.asarray(outline_xz, float)
    edge = np.roll(p, -1, axis=0) - p
    normal = np.stack([edge[:, 1], -edge[:, 0]], 1)              # outward for a counter-clockwise polygon
    best = 0.0
    for p0, p1 in segments:
        a, d = p0[:, [0, 2]], (p1 - p0)[:, [0, 2]]
        num = (p[None] - a[:, None]) * normal[None]                # (N, n, 2)
        num = num.sum(-1)
        den = (d[:, None] * normal[None]).sum(-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / den
        enter = np.where(den < 0, t, -np.inf).max(1)
        leave = np.where(den > 0, t, np.inf).min(1)
        outside = np.any((den == 0) & (num < 0), axis=1)
        t0, t1 = np.maximum(enter, 0.0), np.minimum(leave, 1.0)
        ok = ~outside & (t0 <= t1)
        if ok.any():
            y0 = p0[ok, 1] + t0[ok] * (p1 - p0)[ok, 1]
            y1 = p0[ok, 1] + t1[ok] * (p1 - p0)[ok, 1]
            best = max(best, float(np.abs(y0).max()), float(np.abs(y1).max()))
    return best


def _ccw_hull(points_xz: np.ndarray) -> np.ndarray:
    hull = ConvexHull(points_xz)
    return points_xz[hull.vertices]          # scipy gives 2-D hulls counter-clockwise


def glass_extents(design: MirrorDesign, params: MountParams) -> dict[str, MirrorExtent]:
    """Each mirror's glass rectangle: the design's, taller above and below by ``m1_border_mm`` for M1 (its
    contacts) and :data:`CLIP_BORDER_MM` for the others (their springs), so nothing touches the light."""
    out = {}
    for n in MIRROR_NAMES:
        e = design.rig.mirrors.extent(n)
        b = params.m1_border_mm if n == "m1" else CLIP_BORDER_MM
        out[n] = MirrorExtent(e.along_mm, (e.height_mm[0] - b, e.height_mm[1] + b))
    return out


def mount_layout(design: MirrorDesign, params: MountParams = MountParams(), far_mm: float = 1200.0,
                 segments: list | None = None) -> MountLayout:
    """The mount for a designed rig (:func:`psvs.optics.design.design_mirrors`) as plain parts.

    ``segments``: the field rays' legs (:func:`field_segments`; traced here when None). Raises
    :class:`MountError` naming the culprit: the design's own blockage, M1's contacts in the light, the
    lens barrel in the M1 plate, the clamp in the lid."""
    if not design.ok:
        raise MountError("the layout is blocked: " + "; ".join(design.problems))
    rig = design.rig
    glass = glass_extents(design, params)
    _check_glass_clear(rig, glass)
    segs = field_segments(rig, far_mm) if segments is None else segments
    seats = seats_for(rig, pitch_mm=params.pitch_mm, inset=DEFAULT_INSET, glass_mm=params.glass_mm,
                      m1_border_mm=params.m1_border_mm)
    planes = mirror_planes(rig)
    # M1's strips lie beyond the light in height (below), the others' walls beside it along the glass
    ranges = {n: carrier_range(n, planes[n], glass[n], seats[n], params, segs) for n in MIRROR_NAMES[1:]}
    ranges["m1"] = (glass["m1"].along_mm[0] - params.plate_mm, glass["m1"].along_mm[1] + params.plate_mm)
    feet = {n: _carrier_footprint(planes[n], ranges[n], seats[n], params) for n in MIRROR_NAMES}
    strip = _m1_strip_start(planes, glass, seats, params, ranges,
                            max_abs_y_over(_ccw_hull(feet["m1"]), segs) + params.light_margin_mm)
    iface = _interface_footprint(params)
    hull = _ccw_hull(np.concatenate(list(feet.values()) + [iface]))
    top = max(max(abs(v) for e in glass.values() for v in e.height_mm) + params.clearance_mm,
              max_abs_y_over(hull, segs) + params.light_margin_mm, params.lens_diameter_mm / 2 + params.plate_mm,
              _clamp_height(params) + params.wall_mm if params.interface == "clamp" else 0.0)
    _check_m1_contacts(seats["m1"], design.rig.mirrors.extent("m1"), strip, top, params)
    solids = [Slab("floor", tuple(map(tuple, hull)), top, top + params.plate_mm),
              Slab("lid", tuple(map(tuple, hull)), -top - params.plate_mm, -top)]
    cuts, balls, keepouts = [], [], []
    for name in MIRROR_NAMES:
        spans = [(strip, top), (-top, -strip)] if name == "m1" else [(-top, top)]
        s_parts, s_cuts, s_balls = _carrier(name, planes[name], ranges[name], seats[name], params, spans)
        solids += s_parts
        cuts += s_cuts
        balls += s_balls
        keepouts += [Cylinder(c.name.replace("screw", "set screw"), tuple(np.asarray(c.centre) - (
            0.5 * (c.length_mm + SCREW_KEEPOUT_MM)) * planes[name].normal), c.axis,
            SCREW_KEEPOUT_RADIUS_MM + params.light_margin_mm, SCREW_KEEPOUT_MM) for c in s_cuts]
    springs, spring_room = _spring_anchors(planes, glass, design.rig, params, top, hull)
    cuts += springs
    keepouts += spring_room
    i_solids, i_cuts, extra = _interface(params, top)
    _check_lens(rig, params, segs)
    _check_apart([b for b in solids + i_solids + keepouts if isinstance(b, Box)]
                 + _glass_boxes(planes, glass, seats, params))
    return MountLayout(rig, params, tuple(solids + i_solids), tuple(cuts + i_cuts), tuple(balls), glass, seats,
                       float(top), float(strip), extra, keepouts=tuple(keepouts))


def boxes_overlap(a: Box, b: Box, tol_mm: float = 1e-6) -> bool:
    """Do two blocks share volume (deeper than ``tol_mm``; touching faces do not)? The separating-axis test:
    the 3 + 3 face normals and their 9 cross products."""
    ax_a, ax_b = (np.stack([np.asarray(x.x_dir, float), np.cross(x.z_dir, x.x_dir), np.asarray(x.z_dir, float)])
                  for x in (a, b))
    ha, hb = np.asarray(a.size, float) / 2, np.asarray(b.size, float) / 2
    d = np.asarray(b.centre, float) - np.asarray(a.centre, float)
    axes = list(ax_a) + list(ax_b) + [np.cross(u, v) for u in ax_a for v in ax_b]
    for axis in axes:
        n = np.linalg.norm(axis)
        if n < 1e-9:
            continue
        axis = axis / n
        reach = np.abs(ax_a @ axis) @ ha + np.abs(ax_b @ axis) @ hb
        if abs(d @ axis) >= reach - tol_mm:
            return False
    return True


def _glass_boxes(planes: dict, glass: dict, seats: dict, params: MountParams) -> list:
    """Each glass with the gap behind it to its carrier's face (the contacts' standoff), as blocks."""
    out = []
    for name in MIRROR_NAMES:
        p, e, seat = planes[name], glass[name], seats[name]
        (s0, s1), (t0, t1) = e.along_mm, e.height_mm
        depth = seat.back_offset_mm + params.standoff_mm
        c = p.point + 0.5 * (s0 + s1) * p.s_axis + np.array([0.0, 0.5 * (t0 + t1), 0.0]) - 0.5 * depth * p.normal
        out.append(Box(f"{name.upper()} glass (and its seat's gap)", tuple(c), tuple(p.s_axis), tuple(p.normal),
                       (s1 - s0, t1 - t0, depth)))
    return out


def _check_apart(boxes: list) -> None:
    """MountError naming two parts that would cut through each other (the floor and lid touch them by design)."""
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            if boxes_overlap(a, b):
                raise MountError(f"the {a.name} runs into the {b.name} (a smaller --margin-mm or --m1-border-mm, "
                                 "or a layout with more room: psvs design)")


def _check_glass_clear(rig: Rig, glass: dict) -> None:
    """The design's blockage check once more with the glass as cut (M1 taller): MountError if it blocks."""
    from psvs.optics.field import field_pixels
    from psvs.optics.obstruction import find_obstructions
    found = find_obstructions(rig.with_extents(glass), field_pixels(rig.camera))
    if found:
        raise MountError("the glass as cut blocks the light: " + "; ".join(map(str, found))
                         + " (a smaller --m1-border-mm?)")


def _frame(plane) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return plane.s_axis, np.array([0.0, 1.0, 0.0]), plane.normal


def _carrier_span(seat: Seat, params: MountParams) -> tuple[float, float]:
    """The carrier's extent along the normal from the reflecting face, mm: (back, front) both < 0."""
    front = -(seat.back_offset_mm + params.standoff_mm)
    return front - params.plate_mm, front


def _carrier_footprint(plane, s_range: tuple[float, float], seat: Seat, params: MountParams) -> np.ndarray:
    """(4, 2) XZ corners of a carrier seen from above, mm."""
    s_ax, _, n = _frame(plane)
    b, f = _carrier_span(seat, params)
    pts = [plane.point + s * s_ax + k * n for s in s_range for k in (b, f)]
    return np.array(pts)[:, [0, 2]]


def carrier_range(name: str, plane, ext: MirrorExtent, seat: Seat, params: MountParams,
                  segments: list) -> tuple[float, float]:
    """A carrier's extent along its mirror (s, mm): a plate thickness beyond the glass on both sides, cut
    back where field rays cross the carrier's slab behind the glass (seen from above: a ray over the slab
    at any height would meet the carrier, the floor or the lid). MountError when the light leaves no room
    for the contacts."""
    s_ax, _, n = _frame(plane)
    b, f = _carrier_span(seat, params)
    lo, hi = ext.along_mm[0] - params.plate_mm, ext.along_mm[1] + params.plate_mm
    mid = 0.5 * sum(ext.along_mm)
    for p0, p1 in segments:
        s0, s1 = (p0 - plane.point) @ s_ax, (p1 - plane.point) @ s_ax
        k0, k1 = (p0 - plane.point) @ n, (p1 - plane.point) @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (b - k0) / (k1 - k0), (f - k0) / (k1 - k0)
        t0 = np.where(k1 != k0, np.minimum(ta, tb), np.where((k0 >= b) & (k0 <= f), 0.0, np.inf))
        t1 = np.where(k1 != k0, np.maximum(ta, tb), np.where((k0 >= b) & (k0 <= f), 1.0, -np.inf))
        t0, t1 = np.maximum(t0, 0.0), np.minimum(t1, 1.0)
        ok = t0 <= t1
        sa, sb = s0[ok] + t0[ok] * (s1 - s0)[ok], s0[ok] + t1[ok] * (s1 - s0)[ok]
        a, z = np.minimum(sa, sb), np.maximum(sa, sb)
        below, above = (z < mid), (a > mid)
        if np.any(~below & ~above & (z > lo) & (a < hi)):
            raise MountError(f"light crosses behind {name.upper()}'s glass: its carrier has no place")
        lo = max([lo] + list(z[below & (z > lo)] + params.light_margin_mm))
        hi = min([hi] + list(a[above & (a < hi)] - params.light_margin_mm))
    r = max(params.insert_radius_mm, params.standoff_mm) + params.wall_mm
    s_c = seat.contacts_st_mm[:, 0]
    if s_c.min() - r < lo or s_c.max() + r > hi:
        raise MountError(f"the light leaves {name.upper()}'s carrier {hi - lo:.1f} mm along the glass "
                         f"({lo:.1f} .. {hi:.1f} mm), too little for its contacts ({s_c.min():.1f} .. "
                         f"{s_c.max():.1f} mm, Ø{2 * r:.1f} mm with walls)")
    return float(lo), float(hi)


def _spring_anchors(planes: dict, glass: dict, rig: Rig, params: MountParams, top: float,
                    hull: np.ndarray) -> tuple[list, list]:
    """Per mirror, two spring anchors: an M3 insert hole in the floor and one in the lid, :data:`SPRING_REACH_MM`
    in front of the glass's middle; and the springs' room (kept out of the light): from the light's edge plus
    the margin to the floor or lid. MountError when an anchor falls off the floor's outline."""
    holes, room = [], []
    r = params.insert_radius_mm
    edges = np.roll(hull, -1, axis=0) - hull
    for name in MIRROR_NAMES:
        p, g, light = planes[name], glass[name], rig.mirrors.extent(name)
        s_mid = 0.5 * sum(g.along_mm)
        at = p.point + s_mid * p.s_axis + SPRING_REACH_MM * p.normal
        q = at[[0, 2]] - hull
        inside = (edges[:, 0] * q[:, 1] - edges[:, 1] * q[:, 0]) / np.linalg.norm(edges, axis=1)  # > 0 inside
        if inside.min() < r + params.wall_mm:
            raise MountError(f"{name.upper()}'s spring anchor ({at[0]:.1f}, {at[2]:.1f}) mm falls off the floor")
        for side, t_light in ((1.0, light.height_mm[1]), (-1.0, light.height_mm[0])):
            holes.append(Cylinder(f"{name} spring insert {'floor' if side > 0 else 'lid'}",
                                  (at[0], side * (top + params.plate_mm / 2), at[2]), (0.0, 1.0, 0.0), r,
                                  params.plate_mm))             # through: a blind hole would leave 1 mm
            y0 = abs(t_light) + params.light_margin_mm
            if y0 < top:
                c = p.point + s_mid * p.s_axis + 0.5 * (SPRING_REACH_MM + 3.0) * p.normal
                c = c + np.array([0.0, side * 0.5 * (y0 + top), 0.0])
                room.append(Box(f"{name.upper()} spring ({'floor' if side > 0 else 'lid'})", tuple(c), tuple(p.s_axis),
                                tuple(p.normal), (SPRING_WIDTH_MM, top - y0, SPRING_REACH_MM + 3.0)))
    return holes, room


def _m1_strip_start(planes: dict, glass: dict, seats: dict, params: MountParams, ranges: dict,
                    light_mm: float) -> float:
    """How far from the axis plane (|Y|, mm) M1's strips start: beyond the light behind the plate and beyond
    any other mirror's glass (with its seat's gap) that shares their footprint seen from above (M2's end
    sits right behind the plate's on the paper's layout), by the clearance."""
    tall = 1e3
    strip = _carrier("m1", planes["m1"], ranges["m1"], seats["m1"], params, [(-tall, tall)])[0][0]
    start = light_mm
    for box, name in zip(_glass_boxes(planes, glass, seats, params), MIRROR_NAMES, strict=True):
        if name != "m1" and boxes_overlap(strip, Box(box.name, box.centre, box.x_dir, box.z_dir,
                                                          (box.size[0], 2 * tall, box.size[2]))):
            start = max(start, max(abs(v) for v in glass[name].height_mm) + params.clearance_mm)
    return float(start)


def _carrier(name, plane, s_range: tuple[float, float], seat: Seat, params: MountParams, spans):
    """A carrier's plates (one per Y span), its two insert holes and its pivot ball."""
    s_ax, _, n = _frame(plane)
    (s0, s1), (b, f) = s_range, _carrier_span(seat, params)
    s_mid, k_mid = 0.5 * (s0 + s1), 0.5 * (b + f)
    parts = []
    for k, (y0, y1) in enumerate(spans):
        c = plane.point + s_mid * s_ax + k_mid * n + np.array([0.0, 0.5 * (y0 + y1), 0.0])
        # x along s, z along the normal: y = n x s, which is +Y or -Y by the mirror's handedness
        parts.append(Box(f"{name} carrier{'' if len(spans) == 1 else ' ' + 'lower upper'.split()[k]}",
                         tuple(c), tuple(s_ax), tuple(n), (s1 - s0, y1 - y0, f - b)))
    p, h, v = seat.contacts_st_mm
    at = lambda st, k: plane.point + st[0] * s_ax + np.array([0.0, st[1], 0.0]) + k * n  # noqa: E731
    cuts = [Cylinder(f"{name} screw {s}", tuple(at(st, k_mid)), tuple(n), params.insert_radius_mm, f - b)
            for s, st in (("H", h), ("V", v))]
    balls = [Ball(f"{name} pivot", tuple(at(p, f)), params.standoff_mm)]
    return parts, cuts, balls


def _check_m1_contacts(seat: Seat, ext: MirrorExtent, strip: float, top: float, params: MountParams) -> None:
    """M1's contacts must sit on its strips: a wall's width beyond the light behind the plate, and inside
    the glass's borders."""
    r = max(params.insert_radius_mm, params.standoff_mm)
    foot = max(abs(v) for v in ext.height_mm)                   # the light footprint's half height
    need = 2 * (strip + params.wall_mm + r - foot)              # a border whose middle is that far out
    for what, t in zip(("P", "H", "V"), seat.contacts_st_mm[:, 1], strict=True):
        if abs(t) - r < strip + params.wall_mm or abs(t) + r > top - params.wall_mm:
            raise MountError(
                f"M1's contact {what} at {abs(t):.1f} mm from the axis plane lies in the light or off its strip "
                f"(the light behind the plate, or another mirror's glass beside its strips, reaches {strip:.1f} mm): "
                f"make the plate's border wider, "
                f"--m1-border-mm {math.ceil(max(need, params.m1_border_mm) + 0.5)} (now {params.m1_border_mm:g})")


def _interface_footprint(params: MountParams) -> np.ndarray:
    """(4, 2) XZ corners of the clamp block or the flange plate, mm."""
    x0, x1, z0, z1 = _interface_box(params)
    return np.array([[x0, z0], [x1, z0], [x1, z1], [x0, z1]])


def _interface_box(params: MountParams) -> tuple[float, float, float, float]:
    r = params.lens_diameter_mm / 2 + params.clearance_mm / 2
    w = 2 * (r + params.plate_mm)
    if params.interface == "clamp":
        z1 = params.lens_front_mm - 2.0
        return -w / 2, w / 2, z1 - 12.0, z1
    w = max(w, params.hole_square_mm + 2 * params.plate_mm + SCREW_CLEARANCE_MM)
    z0 = -params.flange_mm
    return -w / 2, w / 2, z0, z0 + params.plate_mm


def _interface(params: MountParams, top: float):
    """The clamp block (bored, split above the bore, a screw across the split) or the flange plate (bored,
    four holes), from lid to floor for the flange, from the floor up past the bore for the clamp."""
    x0, x1, z0, z1 = _interface_box(params)
    r = params.lens_diameter_mm / 2 + params.clearance_mm / 2
    zc, length = 0.5 * (z0 + z1), z1 - z0
    axis = (0.0, 0.0, 1.0)
    if params.interface != "clamp":
        plate = Box(f"{params.interface.upper()}-mount flange plate", (0.0, 0.0, zc), (1.0, 0.0, 0.0), axis,
                    (x1 - x0, 2 * top, length))
        a = params.hole_square_mm / 2
        hole_r = SCREW_CLEARANCE_MM / 2 + params.clearance_mm / 2
        if a * math.sqrt(2) - hole_r < r + params.wall_mm:
            least = math.sqrt(2) * (r + params.wall_mm + hole_r)
            raise MountError(f"the camera's holes on a {params.hole_square_mm:g} mm square cut into the lens bore "
                             f"(Ø{2 * r:.1f} mm): the square must exceed {least:.1f} mm")
        holes = [Cylinder("lens bore", (0.0, 0.0, zc), axis, r, length)]
        holes += [Cylinder(f"camera screw {k + 1}", (sx * a, sy * a, zc), axis, hole_r, length)
                  for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1)))]
        return [plate], holes, 0.0
    y_top = -_clamp_height(params)
    if y_top <= -top:
        raise MountError(f"the lens clamp (barrel Ø{params.lens_diameter_mm:g} mm) does not fit under the lid")
    block = Box("lens clamp", (0.0, 0.5 * (y_top + top), zc), (1.0, 0.0, 0.0), axis,
                (x1 - x0, top - y_top, length))
    w = CLAMP_SLIT_MM
    slit = Box("clamp split", (0.0, 0.5 * y_top, zc), (1.0, 0.0, 0.0), axis, (w, -y_top, length))
    y_screw = 0.5 * (y_top - r)
    screw_r = SCREW_CLEARANCE_MM / 2 + params.clearance_mm / 2
    screw = Cylinder("clamp screw", (0.0, y_screw, zc), (1.0, 0.0, 0.0), screw_r, x1 - x0)
    # the split and the bore share the bore's top within |x| < w/2; the screw's hole crosses the split
    shared = length * _segment_area(r, w / 2)
    shared_screw = math.pi * screw_r ** 2 * w
    return [block], [Cylinder("lens bore", (0.0, 0.0, zc), axis, r, length), slit, screw], shared + shared_screw


def _clamp_height(params: MountParams) -> float:
    """How far above the axis the lens clamp's block reaches (its split and screw above the bore), mm."""
    r = params.lens_diameter_mm / 2 + params.clearance_mm / 2
    return r + params.plate_mm + SCREW_CLEARANCE_MM + 2 * params.wall_mm


def _segment_area(r: float, half_w: float) -> float:
    """Area of the upper half-disc of radius r within |x| < half_w, mm^2."""
    g = lambda x: 0.5 * (x * math.sqrt(r * r - x * x) + r * r * math.asin(x / r))  # noqa: E731
    return 2 * g(half_w)


def _check_lens(rig: Rig, params: MountParams, segments: list) -> None:
    """The lens barrel (a cylinder along the axis up to ``lens_front_mm``) must stay clear of the M1 plate's
    box and of every field ray after its first leg (the first leaves through the lens's front)."""
    from psvs.optics.solids import segments_hit
    r, front = params.lens_diameter_mm / 2, params.lens_front_mm
    what = f"the lens barrel (Ø{params.lens_diameter_mm:g} mm, front {front:g} mm ahead of O)"
    ang = np.linspace(0, 2 * math.pi, 72, endpoint=False)
    rim = np.stack([r * np.cos(ang), r * np.sin(ang), np.full_like(ang, front)], 1)
    back = rim - np.array([0.0, 0.0, 50.0])
    if segments_hit(back, rim, "M1 plate", rig).any() or _front_hits(rig, r, front):
        raise MountError(f"{what} reaches the M1 plate")
    for p0, p1 in segments:
        if not np.any(p0):
            continue                                    # camera -> M1: the lens's own light
        d = p1 - p0
        a = d[:, 0] ** 2 + d[:, 1] ** 2
        b = 2 * (p0[:, 0] * d[:, 0] + p0[:, 1] * d[:, 1])
        c = p0[:, 0] ** 2 + p0[:, 1] ** 2 - r * r
        disc = b * b - 4 * a * c
        ok = (disc > 0) & (a > 0)
        sq = np.sqrt(np.where(ok, disc, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = np.maximum((-b - sq) / (2 * a), 0.0), np.minimum((-b + sq) / (2 * a), 1.0)
        z_low = np.minimum(p0[:, 2] + t0 * d[:, 2], p0[:, 2] + t1 * d[:, 2])
        if np.any(ok & (t0 < t1) & (z_low < front)):
            raise MountError(f"{what} blocks the light between the mirrors")


def _front_hits(rig: Rig, r: float, z: float) -> bool:
    """Does the barrel's front disc meet the plate (its corners behind the disc's plane, inside its radius)?"""
    from psvs.optics.obstruction import plate_edges
    plane = mirror_planes(rig)["m1"]
    pts = np.array([p for e in plate_edges(plane, rig.mirrors.plate_thickness_mm) for p in e])
    near = pts[pts[:, 2] <= z]
    return bool(len(near) and (np.hypot(near[:, 0], near[:, 1]) < r).any())
