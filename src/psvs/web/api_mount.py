"""Routes of the Mount step: make the printable mount of the served rig in the page (``psvs mount`` as a library
call, :func:`psvs.mount.build.make_mount`), download its files, and show a mount.stl in 3-D (one made here or by
``psvs mount``)."""
from __future__ import annotations

import base64
import binascii

import numpy as np
from fastapi import APIRouter
from fastapi.responses import JSONResponse, Response

from psvs.mount.cad import MissingExtra, require_cad
from psvs.mount.layout import MountError, MountParams
from psvs.mount.stl_view import mount_mesh
from psvs.web.bodies import MountMakeBody, MountMeshBody
from psvs.web.session import SessionDep

router = APIRouter()

#: The files a mount made in the page offers for download, with their media types (``psvs mount``'s files).
MOUNT_FILES = {"mount.step": "application/step", "mount.stl": "model/stl", "drawing.svg": "image/svg+xml",
               "drawing.png": "image/png", "bom.csv": "text/csv", "mount.toml": "application/toml"}


def _mesh_view(data: bytes, session, name: str) -> dict:
    """A mount's STL as the 3-D view draws it (vertices mm, frame C, 0.01; triangles), its volume and whether it
    is one closed shell; refused when it stands in the served rig's light (:func:`mount_mesh`)."""
    mesh = mount_mesh(data, session.rig, name)
    return {"name": name, "vertices": np.round(mesh.vertices, 2).tolist(), "triangles": mesh.faces.tolist(),
            "volume_cm3": round(float(mesh.volume) / 1000.0, 2), "closed": bool(mesh.is_watertight)}


@router.post("/api/mount/mesh")
def mount_mesh_view(body: MountMeshBody, session: SessionDep):
    """The mount's STL (base64 in the body, as ``psvs mount`` wrote it) as :func:`_mesh_view` gives it."""
    try:
        data = base64.b64decode(body.stl, validate=True)
    except binascii.Error:
        raise ValueError(f"{body.name}: not base64") from None
    return _mesh_view(data, session, body.name)


@router.post("/api/mount/make")
def make_mount_view(body: MountMakeBody, session: SessionDep):
    """Design the served rig's mirrors, build its mount and check it against the optics, as ``psvs mount`` does
    (a few seconds): the mesh for the 3-D view, the checks in a line, and the files to download
    (``GET /api/mount/file/NAME``). 409 without the CAD extra; 422 with the reason when the mount cannot be built
    (a blocked layout, a failed check): nothing kept."""
    try:
        require_cad()
    except MissingExtra as exc:
        return JSONResponse({"detail": str(exc)}, status_code=409)
    from psvs.mount.build import make_mount
    rig = session.rig
    params = MountParams(interface=body.interface, lens_diameter_mm=body.lens_diameter_mm,
                         lens_front_mm=body.lens_front_mm, flange_mm=body.flange_mm,
                         hole_square_mm=body.hole_square_mm, wall_mm=body.wall_mm, clearance_mm=body.clearance_mm,
                         pitch_mm=body.pitch_mm, margin_mm=body.margin_mm)
    try:
        made = make_mount(rig, params, body.near_mm, body.far_mm)
    except MountError as exc:
        return JSONResponse({"detail": f"cannot build the mount: {exc}"}, status_code=422)
    if not session.keep_mount(made.files, rig):
        return JSONResponse({"detail": "the rig was replaced while its mount was made: make it again"},
                            status_code=409)
    c = made.checks
    text = (f"{made.layout.volume_mm3 / 1000:.1f} cm³, one solid; {c.rays} field rays, {c.blocked} blocked; glass "
            f"on its planes within {max(c.glass_error_mm.values()):.3f} mm; STL one closed shell; thinnest wall "
            f"{c.min_wall_mm:.2f} mm")
    return {**_mesh_view(made.files["mount.stl"], session, "mount.stl"), "checks": text,
            "files": [n for n in MOUNT_FILES if n in made.files]}


@router.get("/api/mount/file/{name}")
def mount_file(name: str, session: SessionDep):
    """One file of the mount made in the page as a download: 404 for a name it does not have, 409 before one
    was made for the served rig."""
    if name not in MOUNT_FILES:
        return JSONResponse({"detail": f"a mount's files are {', '.join(MOUNT_FILES)}"}, status_code=404)
    data = session.mount_file(name)
    if data is None:
        return JSONResponse({"detail": "no mount made for this rig yet: make it first"}, status_code=409)
    return Response(data, media_type=MOUNT_FILES[name],
                    headers={"Content-Disposition": f'attachment; filename="{name}"'})
