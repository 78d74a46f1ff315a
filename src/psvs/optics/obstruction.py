"""Does any mirror, or the M1 plate with its thickness, block the other view's light path?

Every segment of each view's chief rays (camera -> M1 -> ... -> last mirror -> scene) is tested against
every solid it does not start or end on: M2, M3, M4 as thin rectangles and the M1 plate as a box (its
front rectangle extruded by the thickness d). Mirrors must have finite extents for this to mean anything.
The test is :func:`psvs.optics.solids.blockers`, the same one that removes blocked rays from every trace
(:func:`psvs.optics.trace.trace_pixels`): what the design calls blocked, the renderer renders blocked.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psvs.optics.mirrors import VIEWS, mirror_planes
from psvs.optics.rig import Rig
from psvs.optics.solids import blockers, path_segments, segments_hit
from psvs.optics.surfaces import Plane
from psvs.optics.trace import trace_pixels


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


def plate_edges(front: Plane, thickness_mm: float) -> list[tuple[np.ndarray, np.ndarray]]:
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


def _segments_hit(p0s, p1s, solid: str, rig: Rig) -> np.ndarray:
    return segments_hit(p0s, p1s, solid, rig)


def find_collisions(rig: Rig) -> list[str]:
    """Pairs of solids (M1 plate box, M2, M3, M4 rectangles) that cut through each other.

    Returns one message per colliding pair, e.g. ``'M2 cuts through the M1 plate'``.
    """
    planes = mirror_planes(rig)
    d = rig.mirrors.plate_thickness_mm
    edges = {"M1 plate": plate_edges(planes["m1"], d)}
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
                hit |= bool(_segments_hit(p0, p1, y, rig).any())
            if hit:
                out.append(f"{b} cuts through the {a}" if a == "M1 plate" else f"{a} and {b} cut through each other")
    return out


def _blocked_segments(rig: Rig, pixels_px: np.ndarray, scene_depth_mm: float):
    """Every (blocker, view, segment, mask (N,)) of the pixels' chief rays, traced through the ideal
    (unbounded) planes, that a solid of ``rig`` blocks on a segment of their path, or that meet their next
    surface behind a segment's start."""
    planes = mirror_planes(rig)
    missing = [n for n in ("m1", "m2", "m3", "m4") if planes[n].extent is None]
    if missing:
        raise ValueError(f"obstruction check needs finite extents on every mirror; unbounded: {', '.join(missing)}")
    ideal = rig.with_extents({n: None for n in ("m1", "m2", "m3", "m4")})
    for view in VIEWS:
        hits: list = []
        rays = trace_pixels(pixels_px, ideal, view, hits)
        blocked_by = blockers(rig, hits, rays.origins_mm, rays.dirs, scene_depth_mm)
        for i, (start, end, _, _) in enumerate(path_segments(hits, rays.origins_mm, rays.dirs, scene_depth_mm)):
            seg = f"{start} -> {end}"
            if i < len(hits):   # the next surface lies behind the segment's start: it cuts into the beam
                yield end, view, seg, rays.valid & ~hits[i][2]
            for solid, where, blocked in blocked_by:
                if where == seg:
                    yield solid, view, seg, rays.valid & blocked


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
    found = []
    for blocker, view, seg, blocked in _blocked_segments(rig, pixels_px, scene_depth_mm):
        if blocked.any():
            k = int(np.flatnonzero(blocked)[0])
            found.append(Obstruction(blocker, view, seg, float(blocked.mean()),
                                     (float(pixels_px[k, 0]), float(pixels_px[k, 1]))))
    return found


#: Samples of the image, columns x rows, over which :func:`blocked_shares` counts (pixel centres of equal cells).
SHARE_GRID = (48, 36)


def share_grid(rig: Rig, grid: tuple[int, int] = SHARE_GRID) -> np.ndarray:
    """The centres (N, 2) px of ``grid`` (columns, rows) equal cells of the rig's image."""
    w, h = rig.camera.image_size_px
    nu, nv = grid
    u = (np.arange(nu) + 0.5) * w / nu - 0.5
    v = (np.arange(nv) + 0.5) * h / nv - 0.5
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def blocked_shares(rig: Rig, grid: tuple[int, int] = SHARE_GRID, scene_depth_mm: float = 2000.0) -> dict[str, float]:
    """The share (0..1) of each view's image (``{'left': ..., 'right': ...}``) whose light some part of the
    layout blocks: the chief rays of the centres of ``grid`` (columns, rows) equal cells of the image, each
    blocked when any segment of its path is (:func:`find_obstructions`' test). :func:`find_obstructions` samples
    the field's border densely, where vignetting starts; this is the image's area that a build loses.

    ``rig`` needs finite extents on all four mirrors (e.g. :func:`psvs.optics.design.design_mirrors`' rig)."""
    pixels = share_grid(rig, grid)
    lost = {view: np.zeros(len(pixels), dtype=bool) for view in VIEWS}
    for _, view, _, blocked in _blocked_segments(rig, pixels, scene_depth_mm):
        lost[view] |= blocked
    return {view: float(m.mean()) for view, m in lost.items()}


def sized_shares(rig: Rig, grid: tuple[int, int] = SHARE_GRID) -> dict[str, float]:
    """The share (0..1) of each view's image that the rig's glass *as sized in it* loses: the centres of ``grid``
    equal cells whose ray misses one of its own finite mirrors or meets another part
    (:func:`psvs.optics.trace.trace_pixels`, what the renderer and the exact model trace). A rig of unbounded
    mirrors (no sizes: the paper's ideal planes) loses nothing."""
    pixels = share_grid(rig, grid)
    return {view: float(np.mean(~trace_pixels(pixels, rig, view).valid)) for view in VIEWS}
