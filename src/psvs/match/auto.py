"""Automatic view separation: pair every left-view edge with its right-view twin, no seed needed.

Each same-row pair of edge pixels (p, q) with d = u_p - u_q in the rig's disparity range votes for
"component of p is the left view of the component of q, at disparity d". A true twin pair gets a vote
from nearly every row of the edge at one disparity (the paper's shape match); accidental alignments are
spread over many disparities. Candidates are ranked by the number of distinct left pixels that agree
within +-1 px and accepted greedily, strongest first, as a unique assignment of *pixels*: every edge
pixel ends up in at most one pair, as the left or the right view. Where the views overlap, the outline of
the union holds pieces of both views in one component; such a component may pair with several others or
with itself (both views of one object merged). A second pass then takes the left edges whose twin is
mostly lost from the edge map where it fell on another object's view: its visible pieces pair, and the
grey image (the sum of both views) must still show the rest. Edges without a strong enough twin are
reported unmatched.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.match.edges import EdgePixels, edge_pixels, row_step, row_votes
from psvs.match.pairs import EdgePair, grow_pairs


@dataclass(frozen=True, eq=False)
class Unmatched:
    """An edge component without a twin: its label, pixel count and bounding box (u0, v0, u1, v1) px."""

    label: int
    n_pixels: int
    bbox_px: tuple[int, int, int, int]


def _n_rows(v: np.ndarray) -> int:
    """Number of distinct rows among row indices v (bincount: no hashing, no sort)."""
    return int(np.count_nonzero(np.bincount(v))) if len(v) else 0


def _distinct(idx: np.ndarray, n: int) -> np.ndarray:
    """Sorted distinct values of integer indices in [0, n) (a mask, not a hash)."""
    m = np.zeros(n, dtype=bool)
    m[idx] = True
    return np.flatnonzero(m)


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


def _candidates(px: EdgePixels, p, q, d, d_min: int, min_rows: int) -> list[dict]:
    """Candidate twins (left component i, right component j, disparity d): every local maximum over d of
    the agreeing rows of a component pair, with its votes (indices into p, q, d within +-1 px)."""
    n_lab = px.n_labels
    span = int(d.max()) - d_min + 3
    key = (px.label[p] * n_lab + px.label[q]) * span + (d - d_min + 1)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    # rows per (i, j, d): distinct (key, row); the keys are sorted, so distinct values come from diff
    rows_of = px.left_uv[1]                                  # rows as the left view sees them
    height = int(rows_of.max()) + 1
    new = np.concatenate(([True], ks[1:] != ks[:-1]))
    first = np.flatnonzero(new)
    uk = ks[first]
    last = np.concatenate((first[1:], [len(ks)]))
    kv = np.sort(ks * height + rows_of[p[order]])
    kv = kv[np.concatenate(([True], kv[1:] != kv[:-1]))] // height
    rcount = np.diff(np.concatenate((np.flatnonzero(np.concatenate(([True], kv[1:] != kv[:-1]))), [len(kv)])))
    rk = kv[np.concatenate(([True], kv[1:] != kv[:-1]))]
    rows = dict(zip(rk.tolist(), rcount.tolist()))
    slices = dict(zip(uk.tolist(), zip(first.tolist(), last.tolist())))
    # every local maximum over d of the (+-1 px smoothed) agreeing rows of a component pair is a candidate:
    # one pair of components can hold two twins at different disparities (merged outlines)
    smooth = {k: rows.get(k - 1, 0) + rows[k] + rows.get(k + 1, 0) for k in uk.tolist()}
    cands = []
    for k, score in smooth.items():
        if score < min_rows or any(smooth.get(k + o, 0) > score for o in (-2, -1, 1, 2)) \
                or smooth.get(k - 1, 0) == score or smooth.get(k - 2, 0) == score:
            continue
        pk = k // span
        idx = np.concatenate([order[slice(*slices[kk])] for kk in (k - 1, k, k + 1) if kk in slices])
        u, v = px.u[p[idx]], px.v[p[idx]]
        cands.append({"i": pk // n_lab, "j": pk % n_lab, "d": int(k % span) + d_min - 1, "votes": idx,
                      "rows": float(score), "box": (u.min(), v.min(), u.max(), v.max())})
    return cands


def _by_support(cands: list[dict], support_px: int):
    """Yield candidates best first: own agreeing rows plus the rows of already *accepted* candidates near
    it (same disparity +-2 px, boxes within ``support_px``: the same object's other edges). The caller
    sends back True when it accepted the candidate it got."""
    if not cands:
        return
    rows = np.array([c["rows"] for c in cands])
    dd = np.array([c["d"] for c in cands])
    box = np.array([c["box"] for c in cands], dtype=float)
    near = ((np.abs(dd[:, None] - dd[None, :]) <= 2)
            & (box[None, :, 0] <= box[:, None, 2] + support_px) & (box[None, :, 2] >= box[:, None, 0] - support_px)
            & (box[None, :, 1] <= box[:, None, 3] + support_px) & (box[None, :, 3] >= box[:, None, 1] - support_px))
    np.fill_diagonal(near, False)
    rank = rows.copy()
    remaining = np.ones(len(cands), dtype=bool)
    while remaining.any():
        k = int(np.argmax(np.where(remaining, rank, -np.inf)))
        remaining[k] = False
        c = cands[k]
        c["rank"] = float(rank[k])
        if (yield c):
            rank += near[:, k] * rows[k]
            yield None  # answer to send()


def _polarity(grey: np.ndarray, px: EdgePixels, level: float) -> np.ndarray:
    """Sign (-1, 0, +1) of the grey step along the row at each edge pixel (0: under ``level``)."""
    if grey.shape != tuple(px.shape):
        raise ValueError(f"grey must have the edge map's shape {tuple(px.shape)}, got {grey.shape}")
    step = row_step(grey, px.u, px.v)
    return np.where(np.abs(step) < level, 0, np.sign(step)).astype(np.int8)


def _step_image(grey: np.ndarray, pad: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`row_step` at every pixel of a grey (H, W) image, and the headroom above the darker of its
    two samples where the brighter one reaches the image's maximum (a step clipped by saturation), else
    infinity; both zero-padded by ``pad`` columns each side: (H, W + 2 pad), column u at u + pad."""
    h, w = grey.shape
    u, v = np.arange(w)[None, :], np.arange(h)[:, None]
    a, b = grey[v, np.clip(u - 2, 0, w - 1)], grey[v, np.clip(u + 2, 0, w - 1)]
    top = grey.max()
    steps, room = np.zeros((h, w + 2 * pad)), np.zeros((h, w + 2 * pad))
    steps[:, pad:pad + w] = row_step(grey, u, v)
    room[:, pad:pad + w] = np.where(np.maximum(a, b) >= top, top - np.minimum(a, b), np.inf)
    room[:, :pad] = room[:, pad + w:] = np.inf
    return steps, room


def _twin_step_seen(steps, px: EdgePixels, idx: np.ndarray, d: float, tol_px: float,
                    level: float, blocked: np.ndarray, view: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Masks (len(idx),) seen and blind, for the twins of edge pixels ``idx`` (taken in ``view``, 0 left or
    1 right) at column u - d of their rows (+-tol_px; on a build, rows and columns of the rectified views,
    :meth:`EdgePixels.twin_pixels`).

    Seen: the grey image steps the same way there, by at least half as much (and ``level``; half the
    headroom where saturation clips the step), and no ``blocked`` pixel lies there: an edge already
    claimed *in the twin's view*. That step is another object's edge in the same view; an edge of the
    *other* view there is what the twin may have merged with. Blind: saturation flattens the whole
    neighbourhood, which can then neither show nor deny the twin. ``steps`` (step, headroom) and
    ``blocked`` are padded images from :func:`_step_image` (same padding).

    The complex image is the *sum* of the two views, so an edge of one view that falls on a bright object
    of the other view still steps the grey level by its own contrast, although both sides of it land above
    the binary threshold and the edge map loses it there.
    """
    step, room = steps
    pad = (step.shape[1] - px.shape[1]) // 2
    u, v = px.u[idx] + pad, px.v[idx]
    own = step[v, u]
    sign = np.sign(own)
    seen = np.zeros(len(idx), dtype=bool)
    other = np.zeros(len(idx), dtype=bool)
    t = int(np.ceil(tol_px))
    blind = np.ones(len(idx), dtype=bool)
    for k in range(-t, t + 1):
        tu, tv, inside = px.twin_pixels(idx, k - np.rint(d), view)
        tu, tv = np.clip(tu + pad, 0, step.shape[1] - 1), np.clip(tv, 0, step.shape[0] - 1)
        step_k = np.where(inside, step[tv, tu], 0.0)            # outside the image: as the zero padding
        room_k = np.where(inside, room[tv, tu], np.inf)
        need = np.maximum(level, 0.5 * np.minimum(np.abs(own), room_k))
        seen |= sign * step_k >= need
        other |= inside & blocked[tv, tu]
        blind &= room_k < level
    return seen & ~other & (sign != 0), blind & ~other


def _claim(claimed: np.ndarray, px: EdgePixels, idx: np.ndarray, view: int) -> None:
    """Mark edge pixels ``idx`` as belonging to ``view`` (0 left, 1 right) in ``claimed`` (2, H, W + 2 pad)."""
    pad = (claimed.shape[2] - px.shape[1]) // 2
    claimed[view, px.v[idx], px.u[idx] + pad] = True


def _row_span(px: EdgePixels, run: np.ndarray) -> int:
    return int(px.v[run].max() - px.v[run].min() + 1)


def _by_label(labels: np.ndarray, n_labels: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices sorted by label, and where each label's run starts (n_labels + 1 offsets): the entries
    with label i are ``order[start[i]:start[i + 1]]``."""
    order = np.argsort(labels, kind="stable")
    return order, np.searchsorted(labels[order], np.arange(n_labels + 1))


def _partly_hidden_twin(px: EdgePixels, votes, index, free, explained, claimed, steps, i: int, ds: int,
                        min_rows: int, min_run: int, tol_px: float, standalone_rows: int, seen_fraction: float,
                        level: float):
    """Accept the twin of left edge ``i`` at disparity ``ds`` from its visible pieces, wherever they are.

    Where one object's view overlaps another object's view, the binary edge map keeps only part of its
    twin's outline, and that part is merged with the other object's outline (or its inner contour). The
    visible pieces are gathered over *all* components at ``ds`` +-1 px (except pixels already claimed for
    the right view); they must agree on at least ``min_rows`` rows in stretches of ``min_run`` rows. The
    rest of the twin must be explained: on at least ``standalone_rows`` rows of edge ``i``, and on
    ``seen_fraction`` of its rows where saturation does not blind the grey image, the grey image steps the
    same way at the twin's column (:func:`_twin_step_seen`), whether the edge map kept that piece or lost
    it on the bright overlap.

    Returns (agreeing left pixels, free pixels of the components holding the twin's pieces) as indices
    into ``px``, or None.
    """
    p, q, d = votes
    (vote_order, vote_start), (pix_order, pix_start) = index
    sel = vote_order[vote_start[i]:vote_start[i + 1]]
    sel = sel[(np.abs(d[sel] - ds) <= 1) & free[p[sel]] & ~explained[p[sel]] & free[q[sel]]
              & (px.label[q[sel]] != i)]
    sel = sel[~claimed[1, px.v[q[sel]], px.u[q[sel]] + (claimed.shape[2] - px.shape[1]) // 2]]
    if _n_rows(px.v[p[sel]]) < min_rows:
        return None
    runs = [r for r in _runs(px, _distinct(p[sel], len(px.u))) if _row_span(px, r) >= min_run]
    kept = np.concatenate(runs) if runs else np.zeros(0, int)
    if _n_rows(px.v[kept]) < min_rows:
        return None
    left = pix_order[pix_start[i]:pix_start[i + 1]]
    left = left[free[left] & ~explained[left]]                  # not already explained by an accepted pair
    seen, blind = _twin_step_seen(steps, px, left, ds, tol_px, level, claimed[1])
    seen_rows = _n_rows(px.v[left[seen]])
    blind_rows = _n_rows(px.v[left]) - _n_rows(px.v[left[~blind]])    # rows with all their twins blind
    if seen_rows < standalone_rows or seen_rows < seen_fraction * (_n_rows(px.v[left]) - blind_rows):
        return None
    in_kept = np.zeros(len(px.u), dtype=bool)
    in_kept[kept] = True
    holders = np.zeros(px.n_labels, dtype=bool)
    holders[px.label[q[sel][in_kept[p[sel]]]]] = True
    return kept, np.flatnonzero(free & holders[px.label])


@dataclass(frozen=True, eq=False)
class AutoMatch:
    pairs: list[EdgePair]
    unmatched: list[Unmatched]
    pixels: EdgePixels


def match_auto(edges: np.ndarray, disparity_range_px: tuple[float, float], min_rows: int = 10,
               min_fraction: float = 0.6, long_run_rows: int = 20, min_run: int = 4, tol_px: float = 2.0,
               support_px: int = 24, standalone_rows: int = 30, grey: np.ndarray | None = None,
               polarity_level: float = 8.0, seen_fraction: float = 0.8, rect=None) -> AutoMatch:
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
    grey : ndarray, shape (H, W), optional
        The (filtered) grey image the edges came from. When given, a vote needs both pixels to step the
        same way across the edge along the row (I(u+2) - I(u-2) of one sign; steps under
        ``polarity_level`` grey levels match either): twins cross the same object boundary.
    standalone_rows : int
        Rows needed by a twin that no accepted pair nearby at the same disparity supports.
    support_px : int
        Candidates are ranked by their agreeing rows plus those of other candidates at the same
        disparity (+-2 px) within this distance: the other edges of the same object (inner contours,
        texture) back the true disparity, which settles repeated shapes (two identical objects).
    seen_fraction : float
        With ``grey``, a second pass accepts a left edge whose twin the edge map keeps only in pieces
        (merged with another object's view): the pieces, gathered over all components at one disparity,
        must agree on ``min_rows`` rows, and the grey image must step the same way at the twin's column
        on this share of the edge's rows and on ``standalone_rows`` rows (:func:`_partly_hidden_twin`).
    rect : psvs.optics.rectify.Rectification, optional
        A build's dual rectification: twins then share rows of the rectified views, and disparities are
        rectified ones. None: the complex image's own rows (the paper's geometry).

    Returns
    -------
    AutoMatch
        ``pairs`` (integer pixel pairs, strongest first; with ``rect`` in rectified coordinates, left and
        right each in its own view's), ``unmatched`` edges (complex-image boxes), and the labelled pixels.
    """
    d_min, d_max = disparity_range_px
    if not 0 < d_min < d_max:
        raise ValueError(f"disparity range must satisfy 0 < d_min < d_max, got {disparity_range_px!r}")
    px = edge_pixels(edges, rect)
    sizes = np.bincount(px.label, minlength=px.n_labels)
    p, q, d = row_votes(px, d_min, d_max)
    pol = None
    if grey is not None and len(p):
        pol = _polarity(np.asarray(grey, dtype=np.float64), px, polarity_level)
        ok = (pol[p] == pol[q]) | (pol[p] == 0) | (pol[q] == 0)
        p, q, d = p[ok], q[ok], d[ok]
    pairs: list[EdgePair] = []
    free = np.ones(len(px.u), dtype=bool)                    # pixels not yet in any pair
    explained = np.zeros(len(px.u), dtype=bool)              # unpaired pixels of a pair whose twin is hidden
    pad = int(np.ceil(d_max + tol_px)) + 1
    steps = None if pol is None else _step_image(np.asarray(grey, dtype=np.float64), pad)
    claimed = np.zeros((2, px.shape[0], px.shape[1] + 2 * pad), dtype=bool)  # known left / right-view pixels

    def accept(i: int, j: int, ds: int, kept: np.ndarray, sel: np.ndarray, right_set: np.ndarray | None) -> bool:
        """Grow the pair (i, j) at disparity ds from its agreeing left pixels ``kept`` (votes ``sel``) along
        both edges (the disparity may drift along a slanted edge); append it if it holds min_rows pixels."""
        in_kept = np.zeros(len(px.u), dtype=bool)
        in_kept[kept] = True
        if i == j:  # a merged outline: the agreeing pixels are the left view, their twins the right
            left_set = kept
            right_set = _distinct(q[sel][in_kept[p[sel]]], len(px.u))
        else:
            left_set = _distinct(np.concatenate([kept, np.flatnonzero(free & (px.label == i))]), len(px.u))
            if right_set is None:
                right_set = np.flatnonzero(free & (px.label == j))
        li, ri = grow_pairs(px, left_set, right_set[~in_kept[right_set]], ds, tol_px, polarity=pol)
        if len(li) < min_rows:
            return False
        left = np.column_stack([c[li] for c in px.left_uv]).astype(float)
        right = np.column_stack([c[ri] for c in px.right_uv]).astype(float)
        pairs.append(EdgePair(left, right, left[:, 0] - right[:, 0], i, j, float(ds)))
        free[li] = False
        free[ri] = False
        _claim(claimed, px, li, 0)
        _claim(claimed, px, ri, 1)
        if pol is not None and i != j:
            # the pair's leftover pixels whose twin steps the grey image where the edge map lost it
            for idx, dd, view in ((np.flatnonzero(free & (px.label == i)), ds, 0),
                                  (np.flatnonzero(free & np.isin(px.label, px.label[ri])), -ds, 1)):
                seen, blind = _twin_step_seen(steps, px, idx, dd, tol_px, polarity_level, claimed[1 - view], view)
                explained[idx[seen | blind]] = True
                _claim(claimed, px, idx[seen], view)
        return True

    later = []                                               # candidates the edge map alone does not settle
    if len(p):
        order = _by_support(_candidates(px, p, q, d, int(d_min), min_rows), support_px)
        for c in order:
            i, j, ds, sel = c["i"], c["j"], c["d"], c["votes"]
            sel = sel[free[p[sel]] & free[q[sel]]]
            runs = _runs(px, _distinct(p[sel], len(px.u)))
            long_runs = [r for r in runs if _row_span(px, r) >= min_run]
            kept = np.concatenate(long_runs) if long_runs else np.zeros(0, int)
            agree = _n_rows(px.v[kept])                              # distinct agreeing rows
            longest = max((_row_span(px, r) for r in long_runs), default=0)
            rows_i = _n_rows(px.v[free & (px.label == i)])
            rows_j = _n_rows(px.v[free & (px.label == j)])
            # a merged outline (both views in one component) pairs with itself: half is left, half right
            smaller = rows_i / 2 if i == j else min(rows_i, rows_j)
            # an edge backed by no accepted pair at its disparity nearby needs stronger evidence of its own
            need = min_rows if c["rank"] > c["rows"] else standalone_rows
            if agree < need or (agree < min_fraction * smaller and longest < long_run_rows):
                if pol is not None and i != j:
                    later.append(c)
                continue
            if accept(i, j, ds, kept, sel, None):
                order.send(True)
    # Second pass, once the edge map has settled what it can (so it never takes a pixel a first-pass pair
    # needed): twins partly hidden on, or merged with, another object's view.
    index = (_by_label(px.label[p], px.n_labels), _by_label(px.label, px.n_labels))  # votes, pixels by component
    tried = set()                                            # (i, d) found wanting since the last acceptance
    for c in later:
        i, ds = c["i"], c["d"]
        if (i, ds) in tried or _n_rows(px.v[free & (px.label == i)]) < standalone_rows:
            continue
        tried.add((i, ds))
        hidden = _partly_hidden_twin(px, (p, q, d), index, free, explained, claimed, steps, i, ds, min_rows,
                                     min_run, tol_px, standalone_rows, seen_fraction, polarity_level)
        if hidden is not None and accept(i, c["j"], ds, hidden[0], c["votes"], hidden[1]):
            tried.clear()
    unmatched = []
    paired = np.bincount(px.label[~free | explained], minlength=px.n_labels)
    for lab in range(px.n_labels):
        if paired[lab] >= 0.5 * sizes[lab]:
            continue  # mostly paired; stray pixels of a paired edge are not an unmatched edge
        sel = (px.label == lab) & free
        u, v = px.u[sel], px.v[sel]
        unmatched.append(Unmatched(int(lab), int(sel.sum()), (int(u.min()), int(v.min()), int(u.max()), int(v.max()))))
    return AutoMatch(pairs, unmatched, px)
