"""The mount checked against the optics, on the mesh that will be printed (trimesh ray casting).

- **Light.** Every traced field ray of both views (:func:`psvs.mount.layout.field_segments`: camera ->
  each mirror -> the working range's far end) is cast against the mesh, leg by leg; a ray that meets it
  before the leg's end is blocked, and the part it meets is named.
- **Glass.** Each mirror rests on its three contacts: the pivot's apex is *measured* on the mesh (a ray
  cast at it from the glass's side), the screw holes are found open along their axes, the screws' tips
  stand the nominal ``standoff`` proud; the glass's reflecting face through them is compared with the
  designed plane at its corners. Rays cast from a grid on each glass's front face find no mount inside
  the glass.
- **Printable.** The STL file as written is one closed shell (every edge shared by two faces, no face of zero
  area, one body); the wall thickness, measured inward from points sampled on the surface, is nowhere under the minimum.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from psvs.mount.layout import Box, MountLayout, Slab
from psvs.optics.mirrors import mirror_planes
from psvs.optics.rig import MIRROR_NAMES
from psvs.transforms import transform_from

#: Numerical slack for the mesh's tessellation in the glass and wall checks, mm.
MESH_TOL_MM = 0.05


@dataclass(frozen=True)
class MountChecks:
    """What the checks found: ``rays`` cast, ``blocked`` rays and, per part, how many; ``glass_error_mm``
    per mirror (largest distance of the seated face from its designed plane at the glass's corners) and
    ``glass_intrusion``: mirrors with mount inside their glass; ``watertight``; ``min_wall_mm``."""

    rays: int
    blocked: int
    blocked_by: dict
    hardware_blocked_by: dict
    glass_error_mm: dict
    glass_intrusion: tuple
    watertight: bool
    min_wall_mm: float

    def problems(self, layout: MountLayout) -> list[str]:
        """One line per failed check (empty when the mount is right)."""
        p = layout.params
        out = [f"the {part} blocks {n} of {self.rays} field rays" for part, n in self.blocked_by.items()]
        out += [f"the {part} would block {n} of {self.rays} field rays"
                for part, n in self.hardware_blocked_by.items()]
        out += [f"{m.upper()} sits {e:.3f} mm off its designed plane (more than the clearance {p.clearance_mm:g} mm)"
                for m, e in self.glass_error_mm.items() if e > p.clearance_mm]
        out += [f"the mount cuts into {m.upper()}'s glass" for m in self.glass_intrusion]
        if not self.watertight:
            out.append("the mesh is not one closed shell")
        if self.min_wall_mm < p.wall_mm - MESH_TOL_MM:
            out.append(f"a wall is {self.min_wall_mm:.2f} mm thin (the minimum is {p.wall_mm:g} mm)")
        return out


def printable_mesh(stl_path) -> trimesh.Trimesh:
    """The STL file as written (psvs.mount.cad.write_stl), read by trimesh with nothing repaired."""
    return trimesh.load(str(stl_path), force="mesh")


def one_closed_shell(mesh: trimesh.Trimesh) -> bool:
    """Whether ``mesh`` is a single closed, consistently wound shell: every edge shared by exactly two faces,
    no face of zero area, one connected body."""
    return bool(mesh.is_watertight and mesh.is_volume and mesh.nondegenerate_faces().all()
                and len(mesh.split(only_watertight=False)) == 1)


def check_mount(layout: MountLayout, mesh: trimesh.Trimesh, segments: list, samples: int = 20000,
                seed: int = 0) -> MountChecks:
    """Run every check on ``mesh`` (:func:`printable_mesh`) against ``layout`` and the field rays'
    ``segments`` (:func:`psvs.mount.layout.field_segments`)."""
    rays = sum(len(legs[0][0]) for legs in by_view(segments))
    blocked, by = _light(layout, mesh, segments)
    hardware = hardware_light(layout, segments)
    errors, intrusion = _glass(layout, mesh)
    return MountChecks(int(rays), blocked, by, hardware, errors, intrusion, one_closed_shell(mesh),
                       _min_wall(mesh, samples, seed))


def hardware_mesh(layout: MountLayout) -> trimesh.Trimesh | None:
    """The layout's keep-outs (the set screws behind the carriers, the springs' room) as one mesh (None: none)."""
    parts = []
    for c in layout.keepouts:
        if isinstance(c, Box):
            x, z = np.asarray(c.x_dir, float), np.asarray(c.z_dir, float)
            tf = transform_from(np.column_stack([x, np.cross(z, x), z]), c.centre)
            parts.append(trimesh.creation.box(extents=c.size, transform=tf))
            continue
        turn = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], np.asarray(c.axis, float))
        tf = transform_from(turn[:3, :3], c.centre)
        parts.append(trimesh.creation.cylinder(radius=c.radius_mm, height=c.length_mm, sections=32, transform=tf))
    return trimesh.util.concatenate(parts) if parts else None


def hardware_light(layout: MountLayout, segments) -> dict:
    """Field rays that would meet a keep-out, counted by the nearest keep-out's name."""
    mesh = hardware_mesh(layout)
    if mesh is None:
        return {}
    centres = np.array([c.centre for c in layout.keepouts])
    return _blocked(mesh, segments,
                    lambda q: layout.keepouts[int(np.argmin(np.linalg.norm(centres - q, axis=1)))].name)[1]


def _first_hit(mesh, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance to the first hit along each ray (inf: none), mm, and where (N, 3)."""
    dist = np.full(len(origins), np.inf)
    where = np.full((len(origins), 3), np.nan)
    if not len(origins):
        return dist, where
    loc, idx, _ = mesh.ray.intersects_location(origins, dirs, multiple_hits=False)
    if len(idx):
        d = np.einsum("ij,ij->i", loc - origins[idx], dirs[idx])
        dist[idx], where[idx] = d, loc
    return dist, where


def by_view(segments: list) -> list[list]:
    """The legs of :func:`psvs.mount.layout.field_segments` grouped by view: each view's first leg starts at
    the camera's centre O (the origin)."""
    out: list[list] = []
    for p0, p1 in segments:
        if not np.any(p0) or not out:
            out.append([])
        out[-1].append((p0, p1))
    return out


def _light(layout: MountLayout, mesh, segments) -> tuple[int, dict]:
    """Rays blocked by the mesh on any leg, and how many per part (named from the layout)."""
    return _blocked(mesh, segments, lambda q: _part_at(layout, q))


def _blocked(mesh, segments, name_of) -> tuple[int, dict]:
    """Field rays that meet ``mesh`` on any leg before its end: how many, and how many per ``name_of(point)``
    of the first point met (a ray counted once)."""
    blocked_total, by = 0, {}
    for legs in by_view(segments):
        hit_any = np.zeros(len(legs[0][0]), dtype=bool)
        for p0, p1 in legs:
            d = p1 - p0
            length = np.linalg.norm(d, axis=1)
            dist, where = _first_hit(mesh, p0, d / length[:, None])
            hit = dist < length - 1e-6
            for k in np.flatnonzero(hit & ~hit_any):
                name = name_of(where[k])
                by[name] = by.get(name, 0) + 1
            hit_any |= hit
        blocked_total += int(hit_any.sum())
    return blocked_total, by


def _part_at(layout: MountLayout, point: np.ndarray) -> str:
    """The name of the layout's solid nearest to a point of the mesh."""
    best, name = np.inf, "mount"
    for part in layout.solids:
        if isinstance(part, Box):
            x, z = np.asarray(part.x_dir), np.asarray(part.z_dir)
            axes = np.stack([x, np.cross(z, x), z])
            local = np.abs(axes @ (point - np.asarray(part.centre))) - np.asarray(part.size) / 2
        elif isinstance(part, Slab):
            local = np.array([0.0, max(part.y0 - point[1], point[1] - part.y1), 0.0])
        else:
            continue
        d = float(np.linalg.norm(np.maximum(local, 0.0)))
        if d < best:
            best, name = d, part.name
    return name


def _glass(layout: MountLayout, mesh) -> tuple[dict, tuple]:
    """Per mirror: the seated face's largest distance from its designed plane at the glass's corners, mm;
    and the mirrors whose glass the mesh cuts into."""
    planes = mirror_planes(layout.rig)
    errors, intrusion = {}, []
    for name in MIRROR_NAMES:
        plane, seat, ext = planes[name], layout.seats[name], layout.glass[name]
        s_ax, t_ax, n = plane.s_axis, np.array([0.0, 1.0, 0.0]), plane.normal
        back = seat.back_offset_mm
        on_back = [plane.point + s * s_ax + t * t_ax - back * n for s, t in seat.contacts_st_mm]
        lift = 0.5
        dist, _ = _first_hit(mesh, np.array(on_back) + lift * n, np.tile(-n, (3, 1)))
        pivot_gap = dist[0] - lift                          # the apex measured on the mesh, 0 as designed
        open_holes = dist[1:] - lift >= layout.params.standoff_mm + layout.params.plate_mm - MESH_TOL_MM
        tips = np.array(on_back) - np.array([pivot_gap, 0.0, 0.0])[:, None] * n
        if not np.all(open_holes) or not np.isfinite(pivot_gap):
            errors[name] = float("inf")
            continue
        normal = np.cross(tips[1] - tips[0], tips[2] - tips[0])
        normal *= np.sign(normal @ n) / np.linalg.norm(normal)
        face = tips[0] + back * normal                      # the reflecting face, through the seated glass
        (s0, s1), (t0, t1) = ext.along_mm, ext.height_mm
        corners = np.array([plane.point + s * s_ax + t * t_ax for s in (s0, s1) for t in (t0, t1)])
        # the seated face's distance from the designed plane at each corner, along the designed normal
        lam = ((face - corners) @ normal) / (n @ normal)
        errors[name] = float(np.abs(lam).max())
        grid = np.array([plane.point + s * s_ax + t * t_ax for s in np.linspace(s0, s1, 15)
                         for t in np.linspace(t0, t1, 15)])
        inside, _ = _first_hit(mesh, grid + 0.01 * n, np.tile(-n, (len(grid), 1)))
        if np.any(inside < back + 0.01 - MESH_TOL_MM):
            intrusion.append(name)
    return errors, tuple(intrusion)


def _min_wall(mesh, samples: int, seed: int) -> float:
    """The thinnest wall: from points sampled evenly on the surface, the distance inward (against the
    face's normal) to the next surface, mm (the smallest over the samples)."""
    pts, faces = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    inward = -mesh.face_normals[faces]
    dist, _ = _first_hit(mesh, pts + 1e-4 * inward, inward)
    dist = dist[np.isfinite(dist)]
    return float(dist.min() + 1e-4) if dist.size else float("inf")
