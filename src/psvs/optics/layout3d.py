"""The rig in 3-D, as a layout view draws it (``psvs serve``'s rig view; docs/web.md): the real camera, the
four glasses as the rig file has them (designed, or as calibrated on a build), the two virtual cameras, a
fan of each view's field rays traced through the exact optics (the M1 plate's refraction included) out to
the working range, and each view's field at its near and far depth. Frame C, mm (docs/optics.md)."""
from __future__ import annotations

import dataclasses

import numpy as np

from psvs.optics.design import footprint_extents
from psvs.optics.field import field_pixels
from psvs.optics.mirrors import mirror_planes, virtual_centre
from psvs.optics.rig import Rig
from psvs.optics.surfaces import Plane
from psvs.optics.trace import trace_pixels

VIEWS = ("left", "right")
#: The glasses in the order light meets them, with what each is.
GLASSES = (("m1", "M1 (half-silvered plate)"), ("m2", "M2"), ("m3", "M3"), ("m4", "M4"))


def plane_corners(plane: Plane) -> np.ndarray:
    """The 4 corners (4, 3) mm of a plane's rectangle (its extent about its anchor, along its s and t axes),
    in turn round it."""
    (s0, s1), (t0, t1) = plane.extent.along_mm, plane.extent.height_mm
    return np.array([plane.point + s * plane.s_axis + t * plane.t_axis for s, t in ((s0, t0), (s1, t0), (s1, t1),
                                                                                   (s0, t1))])


def fan_pixels(rig: Rig, per_side: int = 3) -> np.ndarray:
    """A ``per_side`` x ``per_side`` grid of pixels (n, 2) over the image, corners included (pixel centres of
    the outermost rows and columns), row by row."""
    w, h = rig.camera.image_size_px
    u, v = np.meshgrid(np.linspace(0, w - 1, per_side), np.linspace(0, h - 1, per_side))
    return np.column_stack([u.ravel(), v.ravel()])


def ray_paths(rig: Rig, view: str, uv_px: np.ndarray, far_mm: float) -> list[np.ndarray]:
    """Each pixel's ray of one view as a polyline (k, 3) mm: the camera's centre O, its hit on each surface
    of the view's path (the plate's two faces for the left view), then the point at depth Z = ``far_mm``;
    only the rays the view really sees (not vignetted, not blocked)."""
    hits: list = []
    rays = trace_pixels(uv_px, rig, view, hits)
    out = []
    for k in np.flatnonzero(rays.valid):
        o, d = rays.origins_mm[k], rays.dirs[k]
        if d[2] <= 0:
            continue
        end = o + (far_mm - o[2]) / d[2] * d
        out.append(np.vstack([np.zeros(3), *[h[1][k] for h in hits], end]))
    return out


def field_at(rig: Rig, view: str, z_mm: float) -> np.ndarray | None:
    """A view's field at depth ``z_mm``: where its rays through the image's 4 corners cross Z = z_mm, (4, 3)
    mm in turn round it; None when a corner's ray is not seen."""
    w, h = rig.camera.image_size_px
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    rays = trace_pixels(corners, rig, view)
    if not rays.valid.all() or (rays.dirs[:, 2] <= 0).any():
        return None
    t = (z_mm - rays.origins_mm[:, 2]) / rays.dirs[:, 2]
    return rays.origins_mm + t[:, None] * rays.dirs


def rig_layout(rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0, per_side: int = 3) -> dict:
    """The rig's layout (module docstring) as plain arrays, mm, frame C:

    - ``camera``: the real camera's centre O (3,);
    - ``glasses``: [{``name``, ``label``, ``corners_mm`` (4, 3), ``sized``}] of each glass (the plate's front
      face for M1, its ``back_mm`` (4, 3) too when it has a thickness): its rectangle in the rig file
      (``sized`` "rig file"), or where the rig file gives none (the paper's unbounded planes) the footprint of
      the camera's whole field on it (``sized`` "field footprint", :func:`psvs.optics.design.footprint_extents`);
    - ``virtual``: {view: the virtual camera's centre (3,)} (O1 left, O2 right; eqs. 1-8's construction);
    - ``rays``: {view: [polyline (k, 3)]} of a ``per_side`` x ``per_side`` fan of pixels, out to ``far_mm``;
    - ``field``: {view: {``near``: (4, 3) or None, ``far``: (4, 3) or None}}: the view's field there;
    - ``range_mm``: (near, far);
    - ``designed``: for a build (a mirror off its designed pose, or the box turned), [{``name``, ``corners_mm``
      (4, 3)}] of each glass where its design puts it (the same rectangles, no pose error); None for a design.
    """
    if not 0 < near_mm < far_mm:
        raise ValueError(f"the working range must be 0 < near < far mm, got {near_mm:g} and {far_mm:g}")
    planes = mirror_planes(rig)
    footprint = None
    glasses = []
    for name, label in GLASSES:
        sized, faces = "rig file", [planes[name]] + ([planes["m1_back"]] if name == "m1" and
                                                     rig.mirrors.plate_thickness_mm > 0 else [])
        if planes[name].extent is None:
            footprint = footprint or footprint_extents(rig, field_pixels(rig.camera))
            sized, faces = "field footprint", [dataclasses.replace(f, extent=footprint[name]) for f in faces]
        g = {"name": name.upper(), "label": label, "corners_mm": plane_corners(faces[0]), "sized": sized}
        if len(faces) > 1:
            g["back_mm"] = plane_corners(faces[1])
        glasses.append(g)
    designed = None
    if not rig.mirrors.as_designed:
        nominal = rig.designed_mirrors()
        nominal_planes = mirror_planes(nominal)
        designed = [{"name": name.upper(), "corners_mm": plane_corners(
            nominal_planes[name] if nominal_planes[name].extent is not None
            else dataclasses.replace(nominal_planes[name], extent=footprint[name]))} for name, _ in GLASSES]
    uv = fan_pixels(rig, per_side)
    return {"camera": np.zeros(3), "glasses": glasses, "designed": designed,
            "virtual": {v: virtual_centre(rig, v) for v in VIEWS},
            "rays": {v: ray_paths(rig, v, uv, far_mm) for v in VIEWS},
            "field": {v: {"near": field_at(rig, v, near_mm), "far": field_at(rig, v, far_mm)} for v in VIEWS},
            "range_mm": (float(near_mm), float(far_mm))}
