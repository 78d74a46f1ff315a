"""Write matched edges: JSON (the CLI's OUT.json), CSV (one row per pixel pair) and PLY (point cloud)."""
from __future__ import annotations

import io
import json

import numpy as np

from psvs.io.atomic import write_atomic
from psvs.io.jsonsafe import json_safe
from psvs.match.correspondence import MatchResult


def result_to_dict(res: MatchResult, decimals: int | None = None) -> dict:
    """``{"pairs": [...], "unmatched": [...], "disparity_range_px": [...]}`` (px and mm, NaN as null): the one
    form of a match result for files (``psvs match -o``) and the web UI. Each pair: its id, component
    labels, shape disparity, pixel count, median depth and disparity, the pixel pairs, their disparities
    and 3-D points (frame C). ``decimals`` rounds the arrays (the web page's smaller answers)."""
    def arr(a):
        return json_safe(a if decimals is None else np.round(a, decimals))

    pairs = []
    for k, p in enumerate(res.pairs):
        pts = p.points_mm if p.points_mm is not None else np.full((len(p), 3), np.nan)
        pairs.append({"id": k, "left_label": p.left_label, "right_label": p.right_label,
                      "shape_disparity_px": p.shape_disparity_px, "n": len(p),
                      "median_z_mm": p.median_z_mm() if len(p) else None,
                      "median_disparity_px": float(np.median(p.disparity_px)) if len(p) else None,
                      "left_px": arr(p.left_px), "right_px": arr(p.right_px),
                      "disparity_px": arr(p.disparity_px), "points_mm": arr(pts)})
    unmatched = [{"label": u.label, "n_pixels": u.n_pixels, "bbox_px": list(u.bbox_px)} for u in res.unmatched]
    return json_safe({"pairs": pairs, "unmatched": unmatched, "disparity_range_px": list(res.disparity_range_px)})


def write_json(path, res: MatchResult) -> None:
    """Write a match result to ``path`` as JSON (:func:`result_to_dict`), atomically."""
    write_atomic(path, json.dumps(result_to_dict(res)) + "\n")


def write_csv(path, res: MatchResult) -> None:
    """Columns pair,u_l,v_l,u_r,v_r,disparity_px,X_mm,Y_mm,Z_mm (one row per matched pixel)."""
    buf = io.StringIO()
    buf.write("pair,u_l,v_l,u_r,v_r,disparity_px,X_mm,Y_mm,Z_mm\n")
    for k, p in enumerate(res.pairs):
        for (ul, vl), (ur, vr), d, (x, y, z) in zip(p.left_px, p.right_px, p.disparity_px, p.points_mm, strict=True):
            buf.write(f"{k},{ul:.4f},{vl:.4f},{ur:.4f},{vr:.4f},{d:.4f},{x:.4f},{y:.4f},{z:.4f}\n")
    write_atomic(path, buf.getvalue())


def write_ply(path, res: MatchResult) -> None:
    """ASCII PLY of the valid 3-D points (mm) with the pair id as a vertex property."""
    rows = []
    for k, p in enumerate(res.pairs):
        ok = np.all(np.isfinite(p.points_mm), axis=1)
        rows += [f"{x:.4f} {y:.4f} {z:.4f} {k}" for x, y, z in p.points_mm[ok]]
    head = ["ply", "format ascii 1.0", "comment psvs matched edges, frame C, mm", f"element vertex {len(rows)}",
            "property float x", "property float y", "property float z", "property int pair", "end_header"]
    write_atomic(path, "\n".join(head + rows) + "\n")
