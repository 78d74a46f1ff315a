"""Edge maps as labelled pixel sets, and the row votes that pair an edge with its twin.

In a complex image every scene edge appears twice on the same row: in the left view at u_l and in the
right view at u_r = u_l - d with d > 0 inside the rig's disparity range. A *vote* is a pair of edge pixels
(p, q) on one row with d = u_p - u_q in range: p is a candidate left-view pixel, q its right-view twin.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True, eq=False)
class EdgePixels:
    """The edge pixels of an edge map: u, v (N,) int (row-major), component label (N,) (8-connected, from 0),
    the map's shape (H, W) and the number of components."""

    u: np.ndarray
    v: np.ndarray
    label: np.ndarray
    shape: tuple
    n_labels: int


def edge_coords(edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) int64 arrays of an (H, W) bool edge map's pixels, row-major (OpenCV's scan, ~3x np.nonzero)."""
    pts = cv2.findNonZero(edges.view(np.uint8))
    if pts is None:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    pts = pts.reshape(-1, 2)  # (N, 1, 2) in OpenCV 4, (N, 2) in OpenCV 5
    return pts[:, 0].astype(np.int64), pts[:, 1].astype(np.int64)


def edge_pixels(edges: np.ndarray) -> EdgePixels:
    """Label an (H, W) bool edge map into 8-connected components."""
    if edges.ndim != 2 or edges.dtype != bool:
        raise ValueError(f"edges must be an (H, W) bool edge map, got {edges.shape} {edges.dtype}")
    n, labels = cv2.connectedComponents(edges.view(np.uint8), connectivity=8)
    u, v = edge_coords(edges)
    return EdgePixels(u, v, labels[v, u].astype(np.int64) - 1, edges.shape, n - 1)


def row_step(grey: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Grey step along the row, I(u + 2) - I(u - 2), at integer pixels (u, v) of a float (H, W) image
    (columns clipped to the image): its sign is the edge's polarity."""
    w = grey.shape[1]
    return grey[v, np.clip(u + 2, 0, w - 1)] - grey[v, np.clip(u - 2, 0, w - 1)]


def row_votes(px: EdgePixels, d_min: float, d_max: float, left_mask=None, right_mask=None):
    """All same-row pairs (p, q) of edge pixels with d = u_p - u_q in [d_min, d_max].

    ``left_mask`` / ``right_mask`` (N,) restrict which pixels may be p / q. Returns (p, q, d) arrays.
    Pixels are in row-major order (np.nonzero), so the twins of p form one contiguous range of the
    row-major keys v * W + u: found by two binary searches, expanded without Python loops.
    """
    return votes_from_coords(px.u, px.v, d_min, d_max, left_mask, right_mask)


def votes_from_coords(u: np.ndarray, v: np.ndarray, d_min: float, d_max: float, left_mask=None, right_mask=None):
    """:func:`row_votes` on row-major edge coordinates u, v (N,)."""
    n = len(u)
    if n == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0, int)
    width = int(u.max()) + int(d_max) + 2
    key = v * width + u                                   # increasing (row-major order)
    p = np.arange(n) if left_mask is None else np.flatnonzero(left_mask)
    lo = np.searchsorted(key, key[p] - int(np.floor(d_max)), side="left")
    hi = np.searchsorted(key, key[p] - int(np.ceil(d_min)), side="right")
    lo = np.maximum(lo, np.searchsorted(key, v[p] * width, side="left"))   # stay on the row
    counts = np.maximum(hi - lo, 0)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0, int)
    pp = np.repeat(p, counts)
    start = np.repeat(lo - np.cumsum(np.r_[0, counts[:-1]]), counts)
    qq = start + np.arange(total)
    if right_mask is not None:
        keep = right_mask[qq]
        pp, qq = pp[keep], qq[keep]
    return pp, qq, u[pp] - u[qq]
