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
class Roles:
    """Where each edge pixel sits in each view's rectified coordinates (psvs.optics.rectify), rounded to
    integer rectified pixels: ``left`` / ``right`` = (u', v') (N,) int each; ``maps`` = {view: (map_u,
    map_v)} the rectified grid's complex-image pixels (-1 outside the field)."""

    left: tuple
    right: tuple
    maps: dict


@dataclass(frozen=True, eq=False)
class EdgePixels:
    """The edge pixels of an edge map: u, v (N,) int (row-major), component label (N,) (8-connected, from 0),
    the map's shape (H, W) and the number of components.

    ``roles``: on a build, each pixel's coordinates as a left-view pixel and as a right-view pixel, in which
    twins share a row (:class:`Roles`). Without it (the paper's geometry) both are (u, v) itself."""

    u: np.ndarray
    v: np.ndarray
    label: np.ndarray
    shape: tuple
    n_labels: int
    roles: Roles | None = None

    @property
    def left_uv(self) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) (N,) int of every pixel taken as a left-view pixel: the coordinates twins share rows in."""
        return (self.u, self.v) if self.roles is None else self.roles.left

    @property
    def right_uv(self) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) (N,) int of every pixel taken as a right-view pixel."""
        return (self.u, self.v) if self.roles is None else self.roles.right

    def twin_pixels(self, idx: np.ndarray, shift: np.ndarray, view: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Complex-image pixels (u, v) int and an inside mask, (len(idx),) each, of the place ``shift``
        columns along the shared row from pixels ``idx`` taken in ``view`` (0 left, 1 right), read in the
        *other* view: e.g. shift = -d from a left pixel is where its twin at disparity d lies."""
        shift = np.rint(shift).astype(int)
        if self.roles is None:
            return self.u[idx] + shift, self.v[idx], np.ones(len(idx), dtype=bool)
        ru, rv = self.left_uv if view == 0 else self.right_uv
        mu, mv = self.roles.maps["right" if view == 0 else "left"]
        tu, tv = ru[idx] + shift, rv[idx]
        inside = (tu >= 0) & (tu < mu.shape[1]) & (tv >= 0) & (tv < mu.shape[0])
        tu, tv = np.clip(tu, 0, mu.shape[1] - 1), np.clip(tv, 0, mu.shape[0] - 1)
        cu, cv = mu[tv, tu], mv[tv, tu]
        inside &= cu >= 0
        return np.rint(cu).astype(int), np.rint(cv).astype(int), inside


def edge_coords(edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) int64 arrays of an (H, W) bool edge map's pixels, row-major (OpenCV's scan, ~3x np.nonzero)."""
    pts = cv2.findNonZero(edges.view(np.uint8))
    if pts is None:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    pts = pts.reshape(-1, 2)  # (N, 1, 2) in OpenCV 4, (N, 2) in OpenCV 5
    return pts[:, 0].astype(np.int64), pts[:, 1].astype(np.int64)


def edge_pixels(edges: np.ndarray, rect=None) -> EdgePixels:
    """Label an (H, W) bool edge map into 8-connected components; with a rectification
    (psvs.optics.rectify.Rectification), also each pixel's rectified coordinates in both views."""
    if edges.ndim != 2 or edges.dtype != bool:
        raise ValueError(f"edges must be an (H, W) bool edge map, got {edges.shape} {edges.dtype}")
    n, labels = cv2.connectedComponents(edges.view(np.uint8), connectivity=8)
    u, v = edge_coords(edges)
    return EdgePixels(u, v, labels[v, u].astype(np.int64) - 1, edges.shape, n - 1, roles_of(u, v, rect))


def roles_of(u: np.ndarray, v: np.ndarray, rect) -> Roles | None:
    """:class:`Roles` of complex-image pixels (u, v) (N,) under a rectification (None: none needed).
    Pixels whose ray is vignetted in a view get a coordinate far outside that view's rectified image."""
    if rect is None:
        return None
    out = {}
    for view in ("left", "right"):
        r = rect.pixel_table(view)[v, u]
        bad = ~np.all(np.isfinite(r), axis=1)
        r[bad] = -10 ** 6
        out[view] = (np.rint(r[:, 0]).astype(np.int64), np.rint(r[:, 1]).astype(np.int64))
    return Roles(out["left"], out["right"], {view: rect.maps(view) for view in ("left", "right")})


def row_step(grey: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Grey step along the row, I(u + 2) - I(u - 2), at integer pixels (u, v) of a float (H, W) image
    (columns clipped to the image): its sign is the edge's polarity."""
    w = grey.shape[1]
    return grey[v, np.clip(u + 2, 0, w - 1)] - grey[v, np.clip(u - 2, 0, w - 1)]


def row_votes(px: EdgePixels, d_min: float, d_max: float, left_mask=None, right_mask=None):
    """All same-row pairs (p, q) of edge pixels with d = u_p - u_q in [d_min, d_max].

    ``left_mask`` / ``right_mask`` (N,) restrict which pixels may be p / q. Returns (p, q, d) arrays.
    Pixels are in row-major order (np.nonzero), so the twins of p form one contiguous range of the
    row-major keys v * W + u: found by two binary searches, expanded without Python loops. With roles
    (a build), p's row and column are its left-view rectified ones and q's its right-view ones.
    """
    if px.roles is None:
        return votes_from_coords(px.u, px.v, d_min, d_max, left_mask, right_mask)
    return votes_between(*px.left_uv, *px.right_uv, d_min, d_max, left_mask, right_mask)


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


def votes_between(lu, lv, ru, rv, d_min: float, d_max: float, left_mask=None, right_mask=None):
    """:func:`row_votes` where pixel k sits at (lu[k], lv[k]) as a left-view pixel and at (ru[k], rv[k]) as
    a right-view pixel (rectified coordinates, int): pairs (p, q) with lv[p] == rv[q] and
    d = lu[p] - ru[q] in [d_min, d_max]. Returns (p, q, d) arrays, p ascending."""
    n = len(lu)
    empty = (np.zeros(0, int), np.zeros(0, int), np.zeros(0, int))
    if n == 0:
        return empty
    q_all = np.arange(n) if right_mask is None else np.flatnonzero(right_mask)
    p = np.arange(n) if left_mask is None else np.flatnonzero(left_mask)
    q_all = q_all[(ru[q_all] >= 0) & (rv[q_all] >= 0)]
    p = p[(lu[p] >= 0) & (lv[p] >= 0)]
    if len(q_all) == 0 or len(p) == 0:
        return empty
    width = int(max(lu[p].max(), ru[q_all].max())) + int(d_max) + 2
    rkey = rv[q_all] * width + ru[q_all]
    order = np.argsort(rkey, kind="stable")
    rkey, q_sorted = rkey[order], q_all[order]
    pkey = lv[p] * width + lu[p]
    lo = np.searchsorted(rkey, pkey - int(np.floor(d_max)), side="left")
    hi = np.searchsorted(rkey, pkey - int(np.ceil(d_min)), side="right")
    lo = np.maximum(lo, np.searchsorted(rkey, lv[p] * width, side="left"))   # stay on the row
    counts = np.maximum(hi - lo, 0)
    total = int(counts.sum())
    if total == 0:
        return empty
    pp = np.repeat(p, counts)
    start = np.repeat(lo - np.cumsum(np.r_[0, counts[:-1]]), counts)
    qq = q_sorted[start + np.arange(total)]
    return pp, qq, lu[pp] - ru[qq]
