"""Does any mirror, or the M1 plate with its thickness, block the other view's light path?

Every segment of each view's chief rays (camera -> M1 -> ... -> last mirror -> scene) is tested against
every solid it does not start or end on: M2, M3, M4 as thin rectangles and the M1 plate as a box (its
front rectangle extruded by the thickness d). Mirrors must have finite extents for this to mean anything.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psvs.optics.mirrors import VIEWS, mirror_planes
from psvs.optics.rig import Rig
from psvs.optics.surfaces import Plane
from psvs.optics.trace import trace_pixels

_LABEL = {"m1": "M1 plate", "m1_back": "M1 plate", "m2": "M2", "m3": "M3", "m4": "M4"}


@dataclass(frozen=True)
class Obstruction:
    """``blocker`` (e.g. 'M2') blocks ``fraction`` of the sampled ``view`` rays on the segment
    ``segment`` (e.g. 'M1 -> M4'); ``example_px`` is one blocked pixel (u, v)."""

    blocker: str
    view: str
    segment: str
    fraction: float
    example_px: tuple[float, float]

    def __str__(self) -> str:
        u, v = self.example_px
        return (f"{self.blocker} blocks the {self.view} view between {self.segment} "
                f"({100 * self.fraction:.1f} % of the sampled field rays, e.g. pixel ({u:.1f}, {v:.1f}))")


def _hits_rectangle(p0: np.ndarray, p1: np.ndarray, plane: Plane) -> np.ndarray:
    """Mask (N,) of segments p0 -> p1 (N, 3) crossing the plane strictly inside its rectangle."""
    d0 = (p0 - plane.point) @ plane.normal
    d1 = (p1 - plane.point) @ plane.normal
    cross = (d0 * d1) < 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d0 / (d0 - d1)
        x = p0 + t[:, None] * (p1 - p0)
        loc = plane.local(x)
    (s0, s1), (t0, t1) = plane.extent.along_mm, plane.extent.height_mm
    inside = (loc[:, 0] > s0) & (loc[:, 0] < s1) & (loc[:, 1] > t0) & (loc[:, 1] < t1)
    return cross & inside


def _hits_plate(p0: np.ndarray, p1: np.ndarray, front: Plane, thickness_mm: float) -> np.ndarray:
    """Mask (N,) of segments p0 -> p1 that pass through the plate box (slab method in plate coordinates)."""
    (s0, s1), (t0, t1) = front.extent.along_mm, front.extent.height_mm
    lo = np.array([s0, t0, 0.0])
    hi = np.array([s1, t1, thickness_mm])

    def coords(p):  # (s, t, depth into the glass)
        return np.column_stack([front.local(p), (front.point - p) @ front.normal])

    a, b = coords(p0), coords(p1)
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (lo - a) / d, (hi - a) / d
    t_enter = np.nanmax(np.where(d != 0, np.minimum(ta, tb), -np.inf), axis=1)
    t_exit = np.nanmin(np.where(d != 0, np.maximum(ta, tb), np.inf), axis=1)
    outside_slab = np.any((d == 0) & ((a <= lo) | (a >= hi)), axis=1)
    return ~outside_slab & (t_enter < t_exit) & (t_exit > 1e-9) & (t_enter < 1 - 1e-9)


def _plate_edges(front: Plane, thickness_mm: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """The 12 edges of the plate box (or the 4 of the front rectangle when d = 0), as (p0, p1) pairs."""
    front_c = _corners(front)
    if thickness_mm <= 0:
        return [(front_c[i], front_c[(i + 1) % 4]) for i in range(4)]
    back_c = front_c - thickness_mm * front.normal
    edges = []
    for c in (front_c, back_c):
        edges += [(c[i], c[(i + 1) % 4]) for i in range(4)]
    edges += [(front_c[i], back_c[i]) for i in range(4)]
    return edges


def _corners(plane: Plane) -> np.ndarray:
    (s0, s1), (t0, t1) = plane.extent.along_mm, plane.extent.height_mm
    y = np.array([0.0, 1.0, 0.0])
    return np.array([plane.point + s * plane.s_axis + t * y for s, t in ((s0, t0), (s1, t0), (s1, t1), (s0, t1))])


def _segments_hit(p0s, p1s, solid: str, planes: dict, thickness_mm: float) -> np.ndarray:
    if solid == "M1 plate" and thickness_mm > 0:
        return _hits_plate(p0s, p1s, planes["m1"], thickness_mm)
    return _hits_rectangle(p0s, p1s, planes["m1" if solid == "M1 plate" else solid.lower()])


def find_collisions(rig: Rig) -> list[str]:
    """Pairs of solids (M1 plate box, M2, M3, M4 rectangles) that cut through each other.

    Returns one message per colliding pair, e.g. ``'M2 cuts through the M1 plate'``.
    """
    planes = mirror_planes(rig)
    d = rig.mirrors.plate_thickness_mm
    edges = {"M1 plate": _plate_edges(planes["m1"], d)}
    for name in ("m2", "m3", "m4"):
        c = _corners(planes[name])
        edges[name.upper()] = [(c[i], c[(i + 1) % 4]) for i in range(4)]
    solids = list(edges)
    out = []
    for i, a in enumerate(solids):
        for b in solids[i + 1:]:
            hit = False
            for x, y in ((a, b), (b, a)):
                p0 = np.array([e[0] for e in edges[x]])
                p1 = np.array([e[1] for e in edges[x]])
                hit |= bool(_segments_hit(p0, p1, y, planes, d).any())
            if hit:
                out.append(f"{b} cuts through the {a}" if a == "M1 plate" else f"{a} and {b} cut through each other")
    return out


def find_obstructions(rig: Rig, pixels_px: np.ndarray, scene_depth_mm: float = 2000.0) -> list[Obstruction]:
    """Every (blocker, view, segment) for which some of the given field pixels' rays are blocked.

    The chief rays are traced through the ideal (unbounded) planes; a ray is blocked on a segment when
    the segment crosses another solid, or when its next surface lies *behind* it (that surface cuts
    into the beam before the light gets there, e.g. M2 crossing the plate).

    Parameters
    ----------
    rig : Rig
        With finite extents on all four mirrors.
    pixels_px : ndarray, shape (N, 2)
        Field pixels to test, px.
    scene_depth_mm : float
        How far past the last mirror the outgoing rays are followed, mm.
    """
    planes = mirror_planes(rig)
    missing = [n for n in ("m1", "m2", "m3", "m4") if planes[n].extent is None]
    if missing:
        raise ValueError(f"obstruction check needs finite extents on every mirror; unbounded: {', '.join(missing)}")
    ideal = rig.with_extents({n: None for n in ("m1", "m2", "m3", "m4")})
    d = rig.mirrors.plate_thickness_mm
    found = []

    def report(blocker, view, seg, blocked):
        if blocked.any():
            k = int(np.flatnonzero(blocked)[0])
            found.append(Obstruction(blocker, view, seg, float(blocked.mean()),
                                     (float(pixels_px[k, 0]), float(pixels_px[k, 1]))))

    for view in VIEWS:
        hits: list = []
        rays = trace_pixels(pixels_px, ideal, view, hits)
        labels = ["camera"] + [_LABEL[p.name] for p, _, _ in hits] + ["scene"]
        pts = [np.zeros_like(rays.origins_mm)] + [h for _, h, _ in hits]
        pts.append(rays.origins_mm + scene_depth_mm * rays.dirs)
        aheads = [a for _, _, a in hits]
        for i in range(len(pts) - 1):
            seg = f"{labels[i]} -> {labels[i + 1]}"
            if i < len(aheads):
                report(labels[i + 1], view, seg, rays.valid & ~aheads[i])
            ends = {labels[i], labels[i + 1]}
            if ends == {"M1 plate"}:
                continue  # inside the glass
            for solid in ("M1 plate", "M2", "M3", "M4"):
                if solid not in ends:
                    report(solid, view, seg, rays.valid & _segments_hit(pts[i], pts[i + 1], solid, planes, d))
    return found
