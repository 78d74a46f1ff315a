"""A mount's STL read back for viewing beside its rig (the web page's Mount step): ``psvs mount`` writes the
holder in the rig's frame C (mm) and checks that none of the rig's field rays meets it (docs/mount.md). A
mesh made for this rig therefore lets a fan of its field rays pass; one made for another rig (another lens,
baseline or layout), or not in frame C, stands in their way, and is refused rather than drawn in the wrong
place."""
from __future__ import annotations

import io

import numpy as np
import trimesh

from psvs.optics.layout3d import rig_layout
from psvs.optics.rig import Rig

#: Most triangles a mesh for the page may have (``psvs mount``'s are 20 000-60 000).
MAX_FACES = 400_000
#: The fan of field rays (per side, each view) cast against the mesh.
FAN_PER_SIDE = 5


def mount_mesh(data: bytes, rig: Rig, where: str = "mount.stl") -> trimesh.Trimesh:
    """The STL ``data`` (binary or ASCII) as a mesh; ValueError, one line naming ``where``, when it is not an
    STL, holds no triangle or more than :data:`MAX_FACES`, or blocks the rig's light (:func:`blocked_rays`: a
    mount made for another rig)."""
    try:
        mesh = trimesh.load(io.BytesIO(data), file_type="stl", force="mesh")
    except Exception as exc:           # noqa: BLE001 - trimesh raises many kinds on a file that is not one
        raise ValueError(f"{where} is not an STL file ({type(exc).__name__})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{where} holds no triangle (is it an STL file?)")
    if len(mesh.faces) > MAX_FACES:
        raise ValueError(f"{where} holds {len(mesh.faces)} triangles, more than the {MAX_FACES} a view draws")
    if not np.isfinite(mesh.vertices).all():
        raise ValueError(f"{where} has a vertex that is not a finite number")
    hit, total = blocked_rays(mesh, rig)
    if hit:
        raise ValueError(f"{where} stands in the way of {hit} of the rig's {total} field rays: a mount made for "
                         "another rig, or not in the rig's frame")
    return mesh


def blocked_rays(mesh: trimesh.Trimesh, rig: Rig) -> tuple[int, int]:
    """(blocked, cast): of a :data:`FAN_PER_SIDE` squared fan of each view's field rays
    (:func:`psvs.optics.layout3d.rig_layout`), from the first glass to the working range's far end, how many
    meet the mesh (the camera's own leg aside: the lens sits in the holder's barrel)."""
    origins, dirs, lengths, owner = [], [], [], []
    layout = rig_layout(rig, per_side=FAN_PER_SIDE)
    for view in ("left", "right"):
        for j, line in enumerate(layout["rays"][view]):
            line = np.asarray(line)
            for a, b in zip(line[1:-1], line[2:], strict=True):
                seg = b - a
                n = float(np.linalg.norm(seg))
                if n > 0:
                    origins.append(a)
                    dirs.append(seg / n)
                    lengths.append(n)
                    owner.append((view, j))
    if not origins:
        return 0, 0
    o, d, length = np.array(origins), np.array(dirs), np.array(lengths)
    start = o + 1e-3 * d                       # off the glass the segment starts on
    loc, ray, _ = mesh.ray.intersects_location(start, d, multiple_hits=False)
    hit = np.zeros(len(o), dtype=bool)
    hit[ray] = np.linalg.norm(loc - start[ray], axis=1) < length[ray] - 2e-3
    rays_hit = {owner[i] for i in np.flatnonzero(hit)}
    return len(rays_hit), sum(len(layout["rays"][v]) for v in ("left", "right"))
