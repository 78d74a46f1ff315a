"""Depth map and point cloud of a dense left-view disparity map, through the rig's triangulation
(eqs. 12–17, or exact ray tracing), and the cloud's file (binary PLY)."""
from __future__ import annotations

import io
from typing import NamedTuple

import numpy as np

from psvs.imaging.grey import to_grey8
from psvs.io.atomic import write_atomic
from psvs.measure.triangulate import triangulate, twin_rows
from psvs.optics.rig import Rig


class Cloud(NamedTuple):
    """``points_mm`` (N, 3) frame C; ``pixels`` (N, 2) left-view (u, v) of each point; ``depth_mm`` (H, W)
    Z of the left view's pixels, NaN where there is no point."""

    points_mm: np.ndarray
    pixels: np.ndarray
    depth_mm: np.ndarray


def pixel_cloud(disparity, mask, triangulate_pixels) -> Cloud:
    """The cloud of a map's pixels (``disparity`` (H, W), px) with a finite disparity > 0, and in ``mask`` ((H, W)
    bool) when given, row by row: ``triangulate_pixels(uv, d)`` (uv (N, 2) float64 (u, v) on the map's grid, d
    (N,) float64 px) gives their Triangulation; the depth map holds each point's Z, NaN elsewhere. A sparse
    mask (a live loop's strided grid) costs its own pixels, not the map's."""
    d = np.asarray(disparity)
    if d.ndim != 2:
        raise ValueError(f"disparity map must be (H, W), got shape {d.shape}")
    flat = d.ravel()
    if mask is None:
        at = np.flatnonzero(np.isfinite(flat) & (flat > 0))
    else:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != d.shape:
            raise ValueError(f"mask {mask.shape} must have the map's shape {d.shape}")
        at = np.flatnonzero(mask)
        at = at[np.isfinite(flat[at]) & (flat[at] > 0)]
    v, u = np.divmod(at, d.shape[1])        # flat indices: a fraction of 2-D fancy indexing's cost
    uv = np.column_stack([u, v]).astype(np.float64)
    tri = triangulate_pixels(uv, flat[at].astype(np.float64))
    depth = np.full(d.shape, np.nan)
    depth.ravel()[at[tri.valid]] = tri.points_mm[tri.valid, 2]
    return Cloud(tri.points_mm[tri.valid], uv[tri.valid], depth)


def disparity_cloud(disparity_left, rig: Rig, model: str = "refraction", mask=None) -> Cloud:
    """Triangulate every finite pixel of ``disparity_left`` (H, W, px): the left-view pixel (u, v) and its
    right-view twin (u − d, v). ``mask`` (H, W bool) keeps a subset, e.g. ``confidence > 0``. With the exact
    model the twin's row is first moved to where the plate really puts it (:func:`twin_rows`)."""

    def pairs(left, d):
        right = np.column_stack([left[:, 0] - d, left[:, 1]])
        if model == "exact" and len(left):
            right[:, 1], _ = twin_rows(left, right, rig, model="exact")
        return triangulate(left, right, rig, model=model)
    return pixel_cloud(np.asarray(disparity_left, dtype=np.float64), mask, pairs)


def write_cloud_ply(path, cloud: Cloud, grey=None) -> None:
    """Binary little-endian PLY of the cloud's points (float32 mm), with each point's grey level (uchar)
    from the (H, W) image ``grey`` when given. Written atomically."""
    pts = np.asarray(cloud.points_mm, dtype=np.float64)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if grey is not None:
        fields.append(("grey", "u1"))
    rec = np.empty(len(pts), dtype=fields)
    rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    props = ["property float x", "property float y", "property float z"]
    if grey is not None:
        g = np.asarray(grey)
        u, v = cloud.pixels[:, 0].astype(int), cloud.pixels[:, 1].astype(int)
        rec["grey"] = to_grey8(g[v, u])
        props.append("property uchar grey")
    head = "\n".join(["ply", "format binary_little_endian 1.0", "comment psvs dense cloud, frame C, mm",
                      f"element vertex {len(pts)}", *props, "end_header"]) + "\n"
    buf = io.BytesIO()
    buf.write(head.encode("ascii"))
    buf.write(rec.tobytes())
    write_atomic(path, buf.getvalue())
