"""The paper's correspondence algorithm (section III.3, steps 2-8), from one seed pixel on a left-view edge."""
from __future__ import annotations

import cv2
import numpy as np

from psvs.match.edges import edge_pixels, row_votes
from psvs.match.pairs import EdgePair, grow_pairs


def match_seeded(edges: np.ndarray, seed_px, disparity_range_px: tuple[float, float], n_seeds: int = 10,
                 connectivity: int = 4) -> EdgePair:
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

    Returns
    -------
    EdgePair
        Integer pixel pairs (refine with :func:`psvs.match.subpixel.refine_pairs`).
    """
    h, w = edges.shape
    u0, v0 = _check_seed(seed_px, edges)
    if not 2 <= n_seeds <= 100:
        raise ValueError(f"n_seeds must be in 2..100 (the paper's range), got {n_seeds!r}")
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity!r}")
    d_min, d_max = disparity_range_px
    px = edge_pixels(edges)
    lab = px.label[px.index[v0, u0]]
    selected = px.label == lab
    p, q, d = row_votes(px, d_min, d_max, left_mask=selected, right_mask=~selected)
    if len(p) == 0:
        return _empty(lab)
    # shape match: the disparity (+-1 px) shared by the largest number of selected pixels
    counts = np.bincount(d - int(d_min), minlength=int(d_max - d_min) + 3).astype(float)
    smooth = np.convolve(counts, [1, 1, 1], mode="same")
    d_star = int(np.argmax(smooth)) + int(d_min)
    near = np.abs(d - d_star) <= 1
    if smooth.max() < 2:
        return _empty(lab)
    cand_q = q[near]
    order = np.argsort(px.v[cand_q], kind="stable")
    seeds = cand_q[order][np.linspace(0, len(cand_q) - 1, min(n_seeds, len(cand_q))).astype(int)]
    grown = _grow(edges & ~_mask(px, selected, edges.shape), px, seeds, connectivity)
    right_idx = np.flatnonzero(grown[px.v, px.u])
    li, ri = grow_pairs(px, np.flatnonzero(selected), right_idx, d_star)
    if len(li) == 0:
        return _empty(lab)
    left = np.column_stack([px.u[li], px.v[li]]).astype(float)
    right = np.column_stack([px.u[ri], px.v[ri]]).astype(float)
    rlab = int(np.bincount(px.label[ri]).argmax())
    return EdgePair(left, right, left[:, 0] - right[:, 0], int(lab), rlab, float(d_star))


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


def _mask(px, sel, shape):
    m = np.zeros(shape, dtype=bool)
    m[px.v[sel], px.u[sel]] = True
    return m


def _grow(allowed: np.ndarray, px, seeds: np.ndarray, connectivity: int) -> np.ndarray:
    """Pixels of ``allowed`` connected to the seeds through 4- (or 8-) neighbours."""
    n, labels = cv2.connectedComponents(allowed.astype(np.uint8), connectivity=connectivity)
    keep = np.zeros(n, dtype=bool)
    keep[labels[px.v[seeds], px.u[seeds]]] = True
    keep[0] = False
    return keep[labels]


def _empty(lab) -> EdgePair:
    z = np.zeros((0, 2))
    return EdgePair(z, z, np.zeros(0), int(lab), -1, float("nan"))
