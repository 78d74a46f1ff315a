"""The rig's glass as solids, and which traced rays another solid blocks: one test shared by the design's
layout check (:mod:`psvs.optics.obstruction`) and every ray the optics trace (:func:`psvs.optics.trace.trace_pixels`,
hence the renderer, projection and triangulation).

The solids are M2, M3, M4 as thin rectangles and the M1 plate as a box (its front rectangle extruded by the
thickness d along its normal, away from the camera). A ray's path is the polyline camera -> each surface it
meets -> ``scene_depth_mm`` beyond its last mirror; a segment is blocked by every solid it crosses other than
the ones it starts or ends on (the light inside the plate is in the plate). Only finite solids block: an
unbounded mirror is the paper's ideal plane, which would block everything.
"""
from __future__ import annotations

import numpy as np

from psvs.optics.kernels import boxes_meet
from psvs.optics.mirrors import mirror_planes
from psvs.optics.rig import Rig
from psvs.optics.surfaces import Plane

#: What each surface of a path is part of, as the messages name it.
LABEL = {"m1": "M1 plate", "m1_back": "M1 plate", "m2": "M2", "m3": "M3", "m4": "M4"}
SOLIDS = ("M1 plate", "M2", "M3", "M4")
#: How far past its last mirror a ray is followed for blockers, mm (the glass lies within a few hundred mm).
SCENE_DEPTH_MM = 2000.0


def hits_rectangle(p0: np.ndarray, p1: np.ndarray, plane: Plane) -> np.ndarray:
    """Mask (N,) of segments p0 -> p1 (N, 3) crossing the plane strictly inside its rectangle."""
    off = float(plane.point @ plane.normal)
    d0 = p0 @ plane.normal - off
    d1 = p1 @ plane.normal - off
    out = (d0 * d1) < 0
    idx = np.flatnonzero(out)            # only segments that cross the plane can meet its rectangle
    if idx.size:
        a, b = d0[idx], d1[idx]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = p0[idx] + (a / (a - b))[:, None] * (p1[idx] - p0[idx])
        loc = plane.local(x)
        (s0, s1), (t0, t1) = plane.extent.along_mm, plane.extent.height_mm
        out[idx] = (loc[:, 0] > s0) & (loc[:, 0] < s1) & (loc[:, 1] > t0) & (loc[:, 1] < t1)
    return out


def hits_plate(p0: np.ndarray, p1: np.ndarray, front: Plane, thickness_mm: float) -> np.ndarray:
    """Mask (N,) of segments p0 -> p1 that pass through the plate box (slab method in plate coordinates)."""
    off = float(front.point @ front.normal)
    za, zb = off - p0 @ front.normal, off - p1 @ front.normal       # depth into the glass
    out = ~(((za <= 0) & (zb <= 0)) | ((za >= thickness_mm) & (zb >= thickness_mm)))
    out &= np.isfinite(za) & np.isfinite(zb)
    idx = np.flatnonzero(out)            # only segments reaching the slab between the faces can meet the box
    if not idx.size:
        return out
    (s0, s1), (t0, t1) = front.extent.along_mm, front.extent.height_mm
    lo = np.array([s0, t0, 0.0])
    hi = np.array([s1, t1, thickness_mm])
    a = np.column_stack([front.local(p0[idx]), za[idx]])
    b = np.column_stack([front.local(p1[idx]), zb[idx]])
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (lo - a) / d, (hi - a) / d
    t_enter = np.nanmax(np.where(d != 0, np.minimum(ta, tb), -np.inf), axis=1)
    t_exit = np.nanmin(np.where(d != 0, np.maximum(ta, tb), np.inf), axis=1)
    outside_slab = np.any((d == 0) & ((a <= lo) | (a >= hi)), axis=1)
    out[idx] = ~outside_slab & (t_enter < t_exit) & (t_exit > 1e-9) & (t_enter < 1 - 1e-9)
    return out


def segments_hit(p0s: np.ndarray, p1s: np.ndarray, solid: str, rig: Rig) -> np.ndarray:
    """Mask (N,) of segments p0s -> p1s (N, 3) through ``solid`` (one of :data:`SOLIDS`, finite). Only the
    segments whose bounding box meets the solid's are tested exactly."""
    planes = mirror_planes(rig)
    d = rig.mirrors.plate_thickness_mm
    plane = planes["m1" if solid == "M1 plate" else solid.lower()]
    lo, hi = bounding_box(plane, d if solid == "M1 plate" else 0.0)
    idx = np.flatnonzero(boxes_meet(np.ascontiguousarray(p0s, dtype=np.float64),
                                    np.ascontiguousarray(p1s, dtype=np.float64), lo, hi))
    out = np.zeros(len(p0s), dtype=bool)
    if idx.size:
        if solid == "M1 plate" and d > 0:
            out[idx] = hits_plate(p0s[idx], p1s[idx], plane, d)
        else:
            out[idx] = hits_rectangle(p0s[idx], p1s[idx], plane)
    return out


def bounding_box(plane: Plane, thickness_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo (3,), hi (3,)) mm of a mirror's rectangle, extruded by ``thickness_mm`` behind
    its face (the plate), widened by 1e-6 mm."""
    (s0, s1), (t0, t1) = plane.extent.along_mm, plane.extent.height_mm
    c = np.array([plane.point + s * plane.s_axis + t * plane.t_axis for s in (s0, s1) for t in (t0, t1)])
    c = np.concatenate([c, c - thickness_mm * plane.normal])
    return c.min(axis=0) - 1e-6, c.max(axis=0) + 1e-6


def finite_solids(rig: Rig) -> tuple[str, ...]:
    """The solids of :data:`SOLIDS` that have a size in ``rig`` (the plate: M1's rectangle)."""
    m = rig.mirrors
    return tuple(s for s, name in zip(SOLIDS, ("m1", "m2", "m3", "m4"), strict=True) if m.extent(name) is not None)


def path_segments(hits: list, origins_mm: np.ndarray, dirs: np.ndarray, scene_depth_mm: float = SCENE_DEPTH_MM):
    """The polyline of traced rays as (label of its start, label of its end, p0 (N, 3), p1 (N, 3)) per
    segment: camera, each surface of ``hits`` (as :func:`psvs.optics.trace.trace_rays` records them), then
    ``scene_depth_mm`` along ``dirs`` from ``origins_mm`` (the rays' hits on their last mirror)."""
    labels = ["camera"] + [LABEL[p.name] for p, _, _ in hits] + ["scene"]
    pts = [np.zeros_like(origins_mm)] + [h for _, h, _ in hits] + [origins_mm + scene_depth_mm * dirs]
    return [(labels[i], labels[i + 1], pts[i], pts[i + 1]) for i in range(len(pts) - 1)]


def blockers(rig: Rig, hits: list, origins_mm: np.ndarray, dirs: np.ndarray,
             scene_depth_mm: float = SCENE_DEPTH_MM):
    """Every (solid, segment name e.g. 'M3 -> scene', mask (N,)) of rays a finite solid of ``rig`` blocks on
    a segment of their path (:func:`path_segments`) that neither starts nor ends on it."""
    solids = finite_solids(rig)
    out = []
    for start, end, p0, p1 in path_segments(hits, origins_mm, dirs, scene_depth_mm):
        if start == end == "M1 plate":
            continue  # inside the glass
        for solid in solids:
            if solid not in (start, end):
                out.append((solid, f"{start} -> {end}", segments_hit(p0, p1, solid, rig)))
    return out


def occluded(rig: Rig, hits: list, origins_mm: np.ndarray, dirs: np.ndarray,
             scene_depth_mm: float = SCENE_DEPTH_MM) -> np.ndarray:
    """Mask (N,) of traced rays that another finite solid of ``rig`` blocks anywhere on their path."""
    mask = np.zeros(len(origins_mm), dtype=bool)
    for _, _, m in blockers(rig, hits, origins_mm, dirs, scene_depth_mm):
        mask |= m
    return mask
