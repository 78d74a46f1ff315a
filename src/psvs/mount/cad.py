"""The mount as a solid (build123d on OpenCASCADE, the optional extra ``psvs[cad]``): STEP for CAD, STL
for printing, and the checks that read them back (one solid, its volume, a watertight mesh).

Only this module imports build123d, and only when called: the rest of psvs (and ``psvs mount``'s
argument checks) run without it; :func:`require_cad` turns its absence into one line naming the extra.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from psvs.mount.layout import Ball, Box, Cylinder, MountLayout, Slab

#: STL tessellation: chord tolerance (mm) and angle (rad); fine enough for Ø4 holes and the pivots.
STL_TOLERANCE_MM = 0.02
STL_ANGLE_RAD = 0.1


class MissingExtra(RuntimeError):
    """build123d is not installed."""


def require_cad() -> None:
    """MissingExtra (one line naming the extra) when build123d is not importable."""
    if importlib.util.find_spec("build123d") is None:
        raise MissingExtra("the mount needs the optional extra 'cad' (build123d): pip install 'psvs[cad]'")


def _plane(bd, centre, x_dir, z_dir):
    return bd.Plane(origin=tuple(map(float, centre)), x_dir=tuple(map(float, x_dir)), z_dir=tuple(map(float, z_dir)))


def _any_x(axis) -> tuple:
    """A unit vector perpendicular to ``axis`` (3,)."""
    a = np.asarray(axis, float)
    x = np.cross(a, [0.0, 1.0, 0.0] if abs(a[1]) < 0.9 else [1.0, 0.0, 0.0])
    return tuple(x / np.linalg.norm(x))


def _shape(bd, part):
    if isinstance(part, Box):
        return _plane(bd, part.centre, part.x_dir, part.z_dir) * bd.Box(*map(float, part.size))
    if isinstance(part, Slab):
        # a plane at Y = y0 whose normal is +Y: local (u, v) is world (x, -z)
        pl = bd.Plane(origin=(0.0, float(part.y0), 0.0), x_dir=(1.0, 0.0, 0.0), z_dir=(0.0, 1.0, 0.0))
        outline = [(float(x), -float(z)) for x, z in part.outline_xz]
        face = pl * bd.make_face(bd.Polyline(*outline, close=True))
        return bd.extrude(face, amount=float(part.y1 - part.y0), dir=(0.0, 1.0, 0.0))
    if isinstance(part, Cylinder):
        return _plane(bd, part.centre, _any_x(part.axis), part.axis) * bd.Cylinder(part.radius_mm, part.length_mm)
    if isinstance(part, Ball):
        return bd.Pos(*map(float, part.centre)) * bd.Sphere(part.radius_mm)
    raise TypeError(f"no shape for {type(part).__name__}")


def build_solid(layout: MountLayout):
    """The mount as one build123d Part: the solids and balls unioned, the cuts taken away."""
    require_cad()
    import build123d as bd
    body = None
    for part in layout.solids + layout.balls:
        s = _shape(bd, part)
        body = s if body is None else body + s
    for cut in layout.cuts:
        body = body - _shape(bd, cut)
    return body


def write_step(solid, path: Path) -> None:
    """Write the solid to ``path`` as STEP (through build123d); OSError when it cannot be written."""
    import build123d as bd
    if not bd.export_step(solid, str(path)):
        raise OSError(f"build123d could not write {path}")


def write_stl(solid, path: Path) -> None:
    """The solid's tessellation as a binary STL at ``path``, as one closed shell: OpenCASCADE's mesh, once
    stored in float32, holds a few zero-area sliver triangles (each a shell of its own to a reader, its edges
    used once or four times); they are dropped before the file is written, so the file a slicer reads is
    the mesh psvs checked."""
    import build123d as bd
    import trimesh
    raw = path.with_name(path.stem + ".occt.stl")
    if not bd.export_stl(solid, str(raw), tolerance=STL_TOLERANCE_MM, angular_tolerance=STL_ANGLE_RAD):
        raise OSError(f"build123d could not write {path}")
    mesh = trimesh.load(str(raw), force="mesh")
    raw.unlink()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    path.write_bytes(mesh.export(file_type="stl"))


def read_step(path: Path) -> tuple[int, float]:
    """(number of solids, total volume mm^3) of a STEP file, read back through OpenCASCADE."""
    require_cad()
    import build123d as bd
    shape = bd.import_step(str(path))
    solids = shape.solids()
    return len(solids), float(sum(s.volume for s in solids))
