"""The paper's correspondence algorithm (section III.3, steps 2-8), from one seed pixel on a left-view edge."""
from __future__ import annotations

import cv2
import numpy as np

from psvs.match.edges import EdgePixels, edge_coords, roles_of, row_votes
from psvs.match.pairs import EdgePair, grow_pairs


def match_seeded(edges: np.ndarray, seed_px, disparity_range_px: tuple[float, float], n_seeds: int = 10,
                 connectivity: int = 4, rect=None) -> EdgePair:
    """Match the edge under ``seed_px`` (a left-view edge) with its twin, as in the paper.

    Steps: (2) the seed selects its whole connected edge; (3) for every selected pixel, the edge pixels
    on the same row within the disparity range are collected; (4) the disparity shared by the largest
    number of them (the shape match) picks the ``n_seeds`` seeds (2-100) on the corresponding edge,
    spread along it; (5-7) the corresponding edge grows from the seeds through ``connectivity``-neighbours
    (4 in the paper) over edge pixels; (8) each selected pixel is paired with the grown edge's pixel on
    its row nearest to the shape disparity, and the pairing follows the edge where its disparity drifts.

    Parameters
    ----------
    edges : ndarray of bool, shape (H, W)
    seed_px : (u, v)
        An edge pixel of the left view (integers), px.
    disparity_range_px : (d_min, d_max)
        Disparities u_l - u_r the rig can produce in its working range, px.
    rect : psvs.optics.rectify.Rectification, optional
        A build's dual rectification: "the same row" is then a row of the rectified views.

    Returns
    -------
    EdgePair
        Integer pixel pairs (refine with :func:`psvs.match.subpixel.refine_pairs`); with ``rect``, in
        rectified coordinates (left and right each in its own view's).
    """
    u0, v0 = _check_seed(seed_px, edges)
    if not 2 <= n_seeds <= 100:
        raise ValueError(f"n_seeds must be in 2..100 (the paper's range), got {n_seeds!r}")
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity!r}")
    d_min, d_max = disparity_range_px
    e8 = edges.view(np.uint8)
    if not edges.flags.c_contiguous:
        e8 = np.ascontiguousarray(edges).view(np.uint8)
    # (2) the seed's whole connected edge (flood fill touches only that edge), marked 1 in the mask
    h, w = edges.shape
    mask = np.zeros((h + 2, w + 2), np.uint8)
    y0, y1 = _flood(e8, mask, [(u0, v0)], 8, 1)
    # twins lie on the same rows: only the selected edge's row band is scanned for edge pixels (on a
    # build, the twins' rows in the complex image differ: the whole map)
    y0, y1 = (max(0, y0 - 2), min(h, y1 + 2)) if rect is None else (0, h)
    u, v = edge_coords(edges[y0:y1])
    v = v + y0
    px = EdgePixels(u, v, np.zeros(len(u), np.int64), edges.shape, 1, roles_of(u, v, rect))
    selected = mask[v + 1, u + 1] == 1
    # (3) every edge pixel on the same row within the disparity range
    p, q, d = row_votes(px, d_min, d_max, left_mask=selected, right_mask=~selected)
    if len(p) == 0:
        return _empty(0)
    # (4) shape match: the disparity (+-1 px) shared by the largest number of selected pixels
    counts = np.bincount(d - int(d_min), minlength=int(d_max - d_min) + 3).astype(float)
    smooth = np.convolve(counts, [1, 1, 1], mode="same")
    d_star = int(np.argmax(smooth)) + int(d_min)
    if smooth.max() < 2:
        return _empty(0)
    cand_q = q[np.abs(d - d_star) <= 1]
    order = np.argsort(px.v[cand_q], kind="stable")
    seeds = cand_q[order][np.linspace(0, len(cand_q) - 1, min(n_seeds, len(cand_q))).astype(int)]
    # (5-7) the corresponding edge grows from the seeds through 4-neighbours, marked 2 (the selected edge,
    # already marked 1, is a barrier: a flood fill never enters marked mask pixels)
    _flood(e8, mask, list(zip(px.u[seeds].tolist(), px.v[seeds].tolist(), strict=True)), connectivity, 2)
    right_idx = np.flatnonzero(mask[v + 1, u + 1] == 2)
    # (8) pair every selected pixel with the grown edge on its row, following the disparity along the edge
    li, ri = grow_pairs(px, np.flatnonzero(selected), right_idx, d_star)
    if len(li) == 0:
        return _empty(0)
    left = np.column_stack([c[li] for c in px.left_uv]).astype(float)
    right = np.column_stack([c[ri] for c in px.right_uv]).astype(float)
    return EdgePair(left, right, left[:, 0] - right[:, 0], 0, 1, float(d_star))


def _flood(img8: np.ndarray, mask: np.ndarray, seeds, connectivity: int, value: int) -> tuple[int, int]:
    """Mark with ``value`` in ``mask`` ((H+2, W+2) uint8) the pixels of the nonzero image ``img8`` connected to
    the seeds; pixels already marked in the mask are neither entered nor crossed. Returns the filled rows
    [y0, y1)."""
    flags = connectivity | cv2.FLOODFILL_MASK_ONLY | (value << 8)
    y0, y1 = img8.shape[0], 0
    for (su, sv) in seeds:
        if img8[sv, su] and not mask[sv + 1, su + 1]:
            _, _, _, (x, y, w, h) = cv2.floodFill(img8, mask, (int(su), int(sv)), 1, 0, 0, flags)
            y0, y1 = min(y0, y), max(y1, y + h)
    return y0, y1


def _check_seed(seed_px, edges):
    h, w = edges.shape
    try:
        u0, v0 = (int(round(float(c))) for c in seed_px)
    except (TypeError, ValueError):
        raise ValueError(f"seed must be two numbers (u, v), got {seed_px!r}") from None
    if not (0 <= u0 < w and 0 <= v0 < h):
        raise ValueError(f"seed ({u0}, {v0}) is outside the {w}x{h} image")
    if not edges[v0, u0]:
        raise ValueError(f"seed ({u0}, {v0}) is not on an edge pixel (pick a pixel of the edge map)")
    return u0, v0


def _empty(lab) -> EdgePair:
    z = np.zeros((0, 2))
    return EdgePair(z, z, np.zeros(0), int(lab), -1, float("nan"))
