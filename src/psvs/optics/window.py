"""A camera's sensor window (region of interest): the same optics read out over fewer rows.

A machine-vision camera reads a window of its sensor faster than the whole frame (the seam sensor of
psvs.robot reads 32 rows). The window is a camera of its own: the same lens, the principal point moved by
the window's first row. On a build the twins of a point lie rows apart (psvs.optics.rectify), so a window
that must pair its rows grows by that offset, found from the exact optics.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from psvs.optics.project import project_points
from psvs.optics.rectify import needs_rectification
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels


def roi_rig(rig: Rig, rows: int, v0: int | None = None,
            span_mm: tuple[float, float] | None = None) -> tuple[Rig, int]:
    """The rig with its camera read out over ``rows`` image rows centred on the principal point, or from
    row ``v0`` (a sensor window, as a real camera's ROI readout: same optics, the principal point shifted
    by the window's first row). Returns (ROI rig, first row v0 of the window in the full image).

    On a build (the views' rows disagree, :func:`psvs.optics.rectify.needs_rectification`) with the working
    range ``span_mm`` = (near, far) given, the window grows by the twins' row offset over that range (from
    the exact optics, every column): its ``rows`` central left-view rows keep their right-view twins inside
    it, so the sensor pairs as many rows as on the ideal rig."""
    w, h = rig.camera.image_size_px
    if not isinstance(rows, (int, np.integer)) or not 8 <= rows <= h:
        raise ValueError(f"roi_rows must be an integer in 8..{h}, got {rows!r}")
    cx, cy = rig.camera.principal_point_px
    if v0 is None:
        v0 = int(np.clip(round(cy - (rows - 1) / 2), 0, h - rows))
        if span_mm is not None and needs_rectification(rig):
            lo, hi = twin_row_offsets(rig, (v0, v0 + rows - 1), span_mm)
            top, bottom = v0 + min(0, int(np.floor(lo))), v0 + rows + max(0, int(np.ceil(hi)))
            v0, rows = max(0, top), min(h, bottom) - max(0, top)
    cam = replace(rig.camera, image_size_px=(w, int(rows)), principal_point_px=(cx, cy - v0))
    return Rig(cam, rig.mirrors), v0


def twin_row_offsets(rig: Rig, rows: tuple[int, int], span_mm: tuple[float, float]) -> tuple[float, float]:
    """The least and greatest row offset v_right - v_left (px) of a point's two views, for points the left
    view sees on image rows rows[0]..rows[1], at depths Z in span_mm = (near, far) mm: left pixels every
    16 columns traced (exact optics: plate, mirrors, lens) to three depths and projected into the right
    view. (0, 0) when no such point reaches the right view."""
    w, _ = rig.camera.image_size_px
    uu, vv = np.meshgrid(np.arange(0.0, w, 16.0), np.array(rows, float))
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    rays = trace_pixels(uv, rig, "left")
    offsets = []
    for z in np.linspace(span_mm[0], span_mm[1], 3):
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (z - rays.origins_mm[:, 2]) / rays.dirs[:, 2]
        pts = rays.origins_mm + t[:, None] * rays.dirs
        ok = rays.valid & (t > 0)
        if not ok.any():
            continue
        right, seen = project_points(pts[ok], rig, "right")
        offsets.append(right[seen, 1] - uv[ok][seen, 1])
    d = np.concatenate(offsets) if offsets else np.zeros(0)
    return (float(d.min()), float(d.max())) if len(d) else (0.0, 0.0)
