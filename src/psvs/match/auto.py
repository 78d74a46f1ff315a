"""Automatic view separation: pair every left-view edge with its right-view twin, no seed needed.

Each same-row pair of edge pixels (p, q) with d = u_p - u_q in the rig's disparity range votes for
"component of p is the left view of the component of q, at disparity d". A true twin pair gets a vote
from nearly every row of the edge at one disparity (the paper's shape match); accidental alignments are
spread over many disparities. Candidates are ranked by the number of distinct left pixels that agree
within +-1 px and accepted greedily, strongest first, as a unique assignment of *pixels*: every edge
pixel ends up in at most one pair, as the left or the right view. Where the views overlap, the outline of
the union holds pieces of both views in one component; such a component may pair with several others or
with itself (both views of one object merged). Edges without a strong enough twin are reported unmatched.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.match.edges import EdgePixels, edge_pixels, row_votes
from psvs.match.pairs import EdgePair, pair_rows


@dataclass(frozen=True, eq=False)
class Unmatched:
    """An edge component without a twin: its label, pixel count and bounding box (u0, v0, u1, v1) px."""

    label: int
    n_pixels: int
    bbox_px: tuple[int, int, int, int]


def _runs(px: EdgePixels, idx: np.ndarray) -> list[np.ndarray]:
    """Split edge pixels ``idx`` into 8-connected runs (lists of indices)."""
    if len(idx) == 0:
        return []
    u, v = px.u[idx], px.v[idx]
    u0, v0 = u.min(), v.min()
    mask = np.zeros((v.max() - v0 + 1, u.max() - u0 + 1), dtype=np.uint8)
    mask[v - v0, u - u0] = 1
    _, lab = cv2.connectedComponents(mask, connectivity=8)
    run_of = lab[v - v0, u - u0]
    order = np.argsort(run_of, kind="stable")
    cuts = np.flatnonzero(np.diff(run_of[order])) + 1
    return np.split(idx[order], cuts)


def _row_span(px: EdgePixels, run: np.ndarray) -> int:
    return int(px.v[run].max() - px.v[run].min() + 1)


@dataclass(frozen=True, eq=False)
class AutoMatch:
    pairs: list[EdgePair]
    unmatched: list[Unmatched]
    pixels: EdgePixels


def match_auto(edges: np.ndarray, disparity_range_px: tuple[float, float], min_rows: int = 10,
               min_fraction: float = 0.6, long_run_rows: int = 20, min_run: int = 4, tol_px: float = 2.0) -> AutoMatch:
    """Pair all edges of an (H, W) bool edge map with their twins.

    Parameters
    ----------
    edges : ndarray of bool, shape (H, W)
    disparity_range_px : (d_min, d_max)
        Disparities u_l - u_r the rig can produce in its working range, px.
    min_rows : int
        A twin must agree (same disparity +-1 px) on at least this many image rows.
    min_fraction, long_run_rows : float, int
        ... and either on this share of the rows of the smaller of the two edges, or along one contiguous
        stretch of edge spanning at least ``long_run_rows`` rows (a partly hidden edge: its visible part).
    min_run : int
        Agreeing pixels count only in contiguous stretches spanning at least this many rows.
    tol_px : float
        Pixel pairing tolerance around the shape disparity, px.

    Returns
    -------
    AutoMatch
        ``pairs`` (integer pixel pairs, strongest first), ``unmatched`` edges, and the labelled pixels.
    """
    d_min, d_max = disparity_range_px
    if not 0 < d_min < d_max:
        raise ValueError(f"disparity range must satisfy 0 < d_min < d_max, got {disparity_range_px!r}")
    px = edge_pixels(edges)
    sizes = np.bincount(px.label, minlength=px.n_labels)
    p, q, d = row_votes(px, d_min, d_max)
    pairs: list[EdgePair] = []
    used = np.zeros(px.n_labels, dtype=bool)
    if len(p):
        lp, lq = px.label[p], px.label[q]
        span = int(d_max - d_min) + 3
        # count *rows* agreeing per (left component, right component, disparity), then +-1 px smoothing:
        # a near-horizontal stretch holds many pixels in one row and agrees at any disparity
        key = (lp * px.n_labels + lq) * span + (d - int(d_min) + 1)
        height = int(px.v.max()) + 1
        rows = np.unique(key * height + px.v[p])
        uk, cnt = np.unique(rows // height, return_counts=True)
        pair_key, dd = uk // span, uk % span
        smooth = cnt.astype(float)
        for off in (-1, 1):
            nb = np.searchsorted(uk, uk + off)
            ok = (nb < len(uk)) & (uk[np.minimum(nb, len(uk) - 1)] == uk + off) & ((dd + off) >= 0)
            smooth[ok] += cnt[nb[ok]]
        order = np.lexsort((-smooth, pair_key))
        first = np.r_[True, pair_key[order][1:] != pair_key[order][:-1]]
        best = order[first]                                  # best disparity per component pair
        cand_i, cand_j = pair_key[best] // px.n_labels, pair_key[best] % px.n_labels
        cand_d = dd[best] + int(d_min) - 1
        free = np.ones(len(px.u), dtype=bool)            # pixels not yet in any pair
        for k in np.argsort(-smooth[best], kind="stable"):
            i, j, ds = int(cand_i[k]), int(cand_j[k]), int(cand_d[k])
            if smooth[best][k] < min_rows:
                break
            sel = (lp == i) & (lq == j) & (np.abs(d - ds) <= 1) & free[p] & free[q]
            runs = _runs(px, np.unique(p[sel]))
            long_runs = [r for r in runs if _row_span(px, r) >= min_run]
            kept = np.concatenate(long_runs) if long_runs else np.zeros(0, int)
            agree = np.unique(px.v[kept]).size                      # distinct agreeing rows
            longest = max((_row_span(px, r) for r in long_runs), default=0)
            rows_i = np.unique(px.v[free & (px.label == i)]).size
            rows_j = np.unique(px.v[free & (px.label == j)]).size
            # a merged outline (both views in one component) pairs with itself: half is left, half right
            smaller = rows_i / 2 if i == j else min(rows_i, rows_j)
            if agree < min_rows or (agree < min_fraction * smaller and longest < long_run_rows):
                continue
            left_set = kept
            right_set = np.setdiff1d(np.unique(q[sel & np.isin(p, kept)]), left_set)
            li, ri = pair_rows(px, left_set, right_set, ds, tol_px)
            if len(li) < min_rows:
                continue
            left = np.column_stack([px.u[li], px.v[li]]).astype(float)
            right = np.column_stack([px.u[ri], px.v[ri]]).astype(float)
            pairs.append(EdgePair(left, right, left[:, 0] - right[:, 0], i, j, float(ds)))
            free[li] = False
            free[ri] = False
            used[i] = used[j] = True
    unmatched = []
    paired = np.bincount(px.label[~free], minlength=px.n_labels) if len(p) else np.zeros(px.n_labels, int)
    for lab in range(px.n_labels):
        if paired[lab] >= 0.5 * sizes[lab]:
            continue  # mostly paired; stray pixels of a paired edge are not an unmatched edge
        sel = (px.label == lab) & (free if len(p) else True)
        u, v = px.u[sel], px.v[sel]
        unmatched.append(Unmatched(int(lab), int(sel.sum()), (int(u.min()), int(v.min()), int(u.max()), int(v.max()))))
    return AutoMatch(pairs, unmatched, px)
