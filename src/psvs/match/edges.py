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
    """The edge pixels of an edge map: u, v (N,) int, component label (N,) (8-connected, from 0) and a
    (H, W) index image (-1 off edges)."""

    u: np.ndarray
    v: np.ndarray
    label: np.ndarray
    index: np.ndarray
    n_labels: int


def edge_pixels(edges: np.ndarray) -> EdgePixels:
    """Label an (H, W) bool edge map into 8-connected components."""
    if edges.ndim != 2 or edges.dtype != bool:
        raise ValueError(f"edges must be an (H, W) bool edge map, got {edges.shape} {edges.dtype}")
    n, labels = cv2.connectedComponents(edges.astype(np.uint8), connectivity=8)
    v, u = np.nonzero(edges)
    index = np.full(edges.shape, -1, dtype=np.int64)
    index[v, u] = np.arange(len(u))
    return EdgePixels(u.astype(np.int64), v.astype(np.int64), labels[v, u].astype(np.int64) - 1, index, n - 1)


def row_votes(px: EdgePixels, d_min: float, d_max: float, left_mask=None, right_mask=None):
    """All same-row pairs (p, q) of edge pixels with d = u_p - u_q in [d_min, d_max].

    ``left_mask`` / ``right_mask`` (N,) restrict which pixels may be p / q. Returns (p, q, d) arrays.
    Pixels are in row-major order (np.nonzero), so each row is a contiguous, u-sorted run.
    """
    n = len(px.u)
    if n == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0, int)
    starts = np.flatnonzero(np.r_[True, px.v[1:] != px.v[:-1]])
    ends = np.r_[starts[1:], n]
    ps, qs = [], []
    # pair each pixel with the pixels k places before it on its row, for growing k, while any is in range
    row_of = np.repeat(np.arange(len(starts)), ends - starts)
    k = 1
    while True:
        p = np.arange(k, n)
        q = p - k
        same = row_of[p] == row_of[q]
        if not same.any():
            break
        p, q = p[same], q[same]
        d = px.u[p] - px.u[q]
        if d.min() > d_max:
            break
        keep = (d >= d_min) & (d <= d_max)
        ps.append(p[keep])
        qs.append(q[keep])
        k += 1
    p = np.concatenate(ps) if ps else np.zeros(0, int)
    q = np.concatenate(qs) if qs else np.zeros(0, int)
    keep = np.ones(len(p), dtype=bool)
    if left_mask is not None:
        keep &= left_mask[p]
    if right_mask is not None:
        keep &= right_mask[q]
    p, q = p[keep], q[keep]
    return p, q, px.u[p] - px.u[q]
