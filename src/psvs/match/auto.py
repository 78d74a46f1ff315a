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
grey image (the sum of both views) must still show the rest (:mod:`psvs.match.grey_steps`). Edges
without a strong enough twin are reported unmatched.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from psvs._validate import check_count, check_finite
from psvs.match.chance import (
    GAP_PX,
    MIN_BAND_PX,
    Chance,
    Elsewhere,
    NullCandidates,
    chance_level,
    null_bands,
    pair_level,
)
from psvs.match.edges import EdgePixels, edge_pixels, row_votes
from psvs.match.grey_steps import polarity, step_image, twin_step_seen
from psvs.match.pairs import EdgePair, grow_pairs
from psvs.match.pixel_sets import by_label, distinct, joined, long_runs, n_rows, row_span
from psvs.match.rows import RowCheck, row_shift, shift_counts

#: px: the smallest lag at which an edge's twin can be told from the edge itself. Below it the two views'
#: images of one edge overlap within the edge map's width and the shape match's tolerance, and an edge pairs
#: with its own pixels (an adversarial trial: ``--far-mm 50000`` paired 36 of 40 edges with themselves at
#: 2 px, Z 150-1900 m, exit 0). 8 px is a depth of 13 m on the shipped 640 x 480 rig, 29 m on the 1440 x 1080.
MIN_TWIN_LAG_PX = 8.0


def twin_lags(disparity_range_px: tuple[float, float]) -> tuple[float, float]:
    """The disparities (px) an edge matcher searches of a working range's ``disparity_range_px`` (d_min, d_max):
    from :data:`MIN_TWIN_LAG_PX` at least; ValueError when the whole range lies below it (a working range
    so far away that no edge's twin can be told from the edge)."""
    lo, hi = disparity_range_px
    if hi <= MIN_TWIN_LAG_PX:
        raise ValueError(f"the working range's disparities {lo:.1f}..{hi:.1f} px lie below {MIN_TWIN_LAG_PX:g} px, "
                         "where an edge's twin cannot be told from the edge itself: bring --far-mm and --near-mm "
                         "nearer")
    return max(lo, MIN_TWIN_LAG_PX), hi


@dataclass(frozen=True)
class AutoParams:
    """Tuning of :func:`match_auto`; lengths in px of the complex image (of the rectified views on a build).

    Parameters
    ----------
    min_rows : int
        A twin must agree (same disparity +-1 px) on at least this many image rows.
    min_fraction : float
        ... and either on this share (0-1) of the rows of the smaller of the two edges, or along one
        contiguous stretch of edge spanning at least ``long_run_rows`` rows (a partly hidden edge: its
        visible part).
    long_run_rows : int
        See ``min_fraction``.
    min_run : int
        Agreeing pixels count only in contiguous stretches spanning at least this many rows.
    tol_px : float
        Pixel pairing tolerance around the shape disparity, px.
    support_px : int
        Candidates are ranked by their agreeing rows plus those of accepted candidates at the same
        disparity (+-2 px) within this distance, px: the other edges of the same object (inner contours,
        texture) back the true disparity, which settles repeated shapes (two identical objects).
    standalone_rows : int
        Rows needed by a twin that no accepted pair nearby at the same disparity supports.
    polarity_level : float
        With a grey image, a vote needs both pixels to step the same way across the edge along the row
        (I(u+2) - I(u-2) of one sign); steps under this many grey levels match either: twins cross the
        same object boundary.
    seen_fraction : float
        With a grey image, a second pass accepts a left edge whose twin the edge map keeps only in pieces
        (merged with another object's view): the pieces, gathered over all components at one disparity,
        must agree on ``min_rows`` rows, and the grey image must step the same way at the twin's column
        on this share (0-1) of the edge's rows and on ``standalone_rows`` rows
        (:func:`_partly_hidden_twin`).
    """

    min_rows: int = 10
    min_fraction: float = 0.6
    long_run_rows: int = 20
    min_run: int = 4
    tol_px: float = 2.0
    support_px: int = 24
    standalone_rows: int = 30
    polarity_level: float = 8.0
    seen_fraction: float = 0.8

    def __post_init__(self):
        for name in ("min_rows", "long_run_rows", "min_run", "standalone_rows"):
            check_count(getattr(self, name), name, 1)
        check_count(self.support_px, "support_px", 0)
        for name in ("min_fraction", "seen_fraction"):
            if not 0 <= check_finite(getattr(self, name), name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")
        if check_finite(self.tol_px, "tol_px") < 0:
            raise ValueError(f"tol_px must be >= 0 px, got {self.tol_px!r}")
        if check_finite(self.polarity_level, "polarity_level") < 0:
            raise ValueError(f"polarity_level must be >= 0 grey levels, got {self.polarity_level!r}")


@dataclass(frozen=True, eq=False)
class Unmatched:
    """An edge component without a twin: its label, pixel count and bounding box (u0, v0, u1, v1) px."""

    label: int
    n_pixels: int
    bbox_px: tuple[int, int, int, int]


@dataclass(frozen=True, eq=False)
class AutoMatch:
    """Result of :func:`match_auto`: ``pairs`` (integer pixel pairs, strongest first), ``unmatched`` edges
    (complex-image boxes), the labelled edge ``pixels`` and how the candidates stood against ``chance``
    (:class:`psvs.match.chance.Chance`; no pair when it is not ``answered``), and what the pairs said of the
    rig's rows (:class:`psvs.match.rows.RowCheck`; no pair when it ``refuses``)."""

    pairs: list[EdgePair]
    unmatched: list[Unmatched]
    pixels: EdgePixels
    chance: Chance
    rows: RowCheck


@dataclass(frozen=True, eq=False)
class Candidate:
    """A candidate twin: left component ``i`` is the left view of right component ``j`` at disparity ``d``
    px (an integer).

    ``votes`` (K,) int indexes the votes (p, q, d) of the two components within +-1 px of ``d``; ``rows``
    is their agreeing rows, summed over d - 1, d, d + 1; ``box`` (u0, v0, u1, v1) px bounds their left
    pixels in the complex image. ``rank`` is the candidate's support when its turn came: ``rows`` plus the
    rows of the accepted candidates near it (NaN before ranking).
    """

    i: int
    j: int
    d: int
    votes: np.ndarray
    rows: float
    box: tuple[int, int, int, int]
    rank: float = float("nan")


@dataclass(frozen=True, eq=False)
class Evidence:
    """What one call of :func:`match_auto` pairs from, fixed during the call: the labelled edge pixels, the
    votes (p left pixel, q right pixel, d = u_p - u_q px; (V,) each, indices into ``px`` and disparities),
    each pixel's polarity (N,) int8 and the padded step image of the grey image
    (:func:`psvs.match.grey_steps.step_image`), both None without a grey image, and the tuning."""

    px: EdgePixels
    p: np.ndarray
    q: np.ndarray
    d: np.ndarray
    polarity: np.ndarray | None
    steps: tuple[np.ndarray, np.ndarray] | None
    params: AutoParams


class Claims:
    """Which view each edge pixel has been given so far, and the pairs accepted.

    Attributes
    ----------
    free : ndarray of bool, shape (N,)
        Edge pixels in no pair yet.
    explained : ndarray of bool, shape (N,)
        Unpaired pixels of a pair whose twin the grey image shows (or saturation hides) where the edge
        map lost it: not an unmatched edge.
    claimed : ndarray of bool, shape (2, H, W + 2 pad)
        Pixels known to belong to the left (0) or the right (1) view, column u at u + ``pad``.
    pairs : list of EdgePair
        The pairs accepted, in order.
    rows : RowCheck
        The accepted pairs that decisively sit on the rig's rows, and the candidates refused as off them.
    """

    def __init__(self, ev: Evidence, pad: int):
        n = len(ev.px.u)
        self.ev, self.pad = ev, pad
        self.free = np.ones(n, dtype=bool)
        self.explained = np.zeros(n, dtype=bool)
        self.claimed = np.zeros((2, ev.px.shape[0], ev.px.shape[1] + 2 * pad), dtype=bool)
        self.pairs: list[EdgePair] = []
        self.rows = RowCheck()

    def free_of(self, label: int) -> np.ndarray:
        """Mask (N,) of the free pixels of component ``label``."""
        return self.free & (self.ev.px.label == label)

    def free_rows(self, label: int) -> int:
        """Number of distinct rows holding a free pixel of component ``label``."""
        return n_rows(self.ev.px.v[self.free_of(label)])

    def claim(self, idx: np.ndarray, view: int) -> None:
        """Mark edge pixels ``idx`` as belonging to ``view`` (0 left, 1 right)."""
        px = self.ev.px
        self.claimed[view, px.v[idx], px.u[idx] + self.pad] = True

    def accept(self, c: Candidate, kept: np.ndarray, votes: np.ndarray, right: np.ndarray | None = None) -> bool:
        """Grow the pair (c.i, c.j) at disparity c.d from its agreeing left pixels ``kept`` along both edges
        (the disparity may drift along a slanted edge); keep it if it holds ``min_rows`` pixel pairs.

        ``votes`` are the candidate's votes still open: where c.i == c.j (both views merged in one outline)
        the twins of ``kept`` among them are the right view. ``right``: the pixels that may hold the twin
        (None: the free pixels of component c.j). Returns whether the pair was kept.
        """
        ev, prm = self.ev, self.ev.params
        px, n = ev.px, len(ev.px.u)
        in_kept = np.zeros(n, dtype=bool)
        in_kept[kept] = True
        if c.i == c.j:  # a merged outline: the agreeing pixels are the left view, their twins the right
            left_set = kept
            right = distinct(ev.q[votes][in_kept[ev.p[votes]]], n)
        else:
            left_set = distinct(np.concatenate([kept, np.flatnonzero(self.free_of(c.i))]), n)
            if right is None:
                right = np.flatnonzero(self.free_of(c.j))
        li, ri = grow_pairs(px, left_set, right[~in_kept[right]], c.d, prm.tol_px, polarity=ev.polarity)
        if len(li) < prm.min_rows or not self._on_rows(c, left_set, right):
            return False
        left_px = np.column_stack([a[li] for a in px.left_uv]).astype(float)
        right_px = np.column_stack([a[ri] for a in px.right_uv]).astype(float)
        self.pairs.append(EdgePair(left_px, right_px, left_px[:, 0] - right_px[:, 0], c.i, c.j, float(c.d)))
        self.free[li] = False
        self.free[ri] = False
        self.claim(li, 0)
        self.claim(ri, 1)
        if ev.polarity is not None and c.i != c.j:
            self._explain_leftovers(c, ri)
        return True

    def _on_rows(self, c: Candidate, left: np.ndarray, right: np.ndarray) -> bool:
        """Whether the twin of left pixels ``left`` among right pixels ``right`` at disparity ``c.d`` may lie
        on the rig's rows (:mod:`psvs.match.rows`): False, and recorded, when it decisively lies off them. A
        merged outline (both views in one component) is not judged."""
        if c.i == c.j:
            return True
        px = self.ev.px
        rs = row_shift(shift_counts(tuple(a[left] for a in px.left_uv), tuple(a[right] for a in px.right_uv), c.d),
                       self.ev.params.min_rows)
        if rs.verdict == "off":
            self.rows.off.append((float(c.d), rs))
            return False
        self.rows.fits += rs.verdict == "fit"
        return True

    def _explain_leftovers(self, c: Candidate, ri: np.ndarray) -> None:
        """The accepted pair's leftover pixels (free pixels of its left component, and of the components
        holding its right pixels ``ri``) whose twin steps the grey image where the edge map lost it are
        explained and claimed for their view; those where saturation blinds the check are explained."""
        px, prm = self.ev.px, self.ev.params
        leftovers = ((np.flatnonzero(self.free_of(c.i)), c.d, 0),
                     (np.flatnonzero(self.free & np.isin(px.label, px.label[ri])), -c.d, 1))
        for idx, d, view in leftovers:   # the right view's check sees the left view's claims just made
            seen, blind = twin_step_seen(self.ev.steps, px, idx, d, prm.tol_px, prm.polarity_level,
                                         self.claimed[1 - view], view)
            self.explained[idx[seen | blind]] = True
            self.claim(idx[seen], view)


def _peaks(ev: Evidence, d_min: int):
    """The local maxima over d of the agreeing rows of each component pair (smoothed over +-1 px) holding
    ``min_rows`` rows: (their keys (M,), scores (M,)) and, to gather their votes, (the sorted vote keys'
    order, the distinct keys (U,), where each starts in the order (U + 1,)), and the key's span. A key is
    (i * n_labels + j) * span + (d - d_min + 1): its neighbours over d are key +- 1, +- 2 (the offset runs
    1..span - 2, so they never reach another pair's)."""
    px, p, q, d = ev.px, ev.p, ev.q, ev.d
    span = int(d.max()) - d_min + 3
    key = (px.label[p] * px.n_labels + px.label[q]) * span + (d - d_min + 1)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    first = np.flatnonzero(np.concatenate(([True], ks[1:] != ks[:-1])))
    uk = ks[first]
    # rows per (i, j, d): distinct (key, row) pairs counted per key (the keys are sorted)
    rows_of = px.left_uv[1]                                  # rows as the left view sees them
    height = int(rows_of.max()) + 1
    kv = ks * height + rows_of[p[order]]
    if not np.all(kv[1:] >= kv[:-1]):                  # already sorted when rows grow with the pixels' order
        kv.sort()
    kv = kv[np.concatenate(([True], kv[1:] != kv[:-1]))] // height
    rows = np.diff(np.concatenate((np.flatnonzero(np.concatenate(([True], kv[1:] != kv[:-1]))), [len(kv)])))

    def at(values, offset):                 # values[key + offset], 0 where that key holds no vote
        out = np.zeros_like(values)         # key + offset lies at most |offset| places away (distinct keys)
        for step in range(1, abs(offset) + 1):
            here, there = (slice(0, len(uk) - step), slice(step, None))[::1 if offset > 0 else -1]
            hit = uk[there] == uk[here] + offset
            out[here][hit] = values[there][hit]
        return out

    smooth = at(rows, -1) + rows + at(rows, 1)
    near = [at(smooth, o) for o in (-2, -1, 1, 2)]
    keep = (smooth >= ev.params.min_rows) & (near[0] != smooth) & (near[1] != smooth)
    for other in near:
        keep &= other <= smooth
    return uk[keep], smooth[keep].astype(float), (order, uk, np.append(first, len(ks))), span


def _candidates(ev: Evidence, d_min: int) -> list[Candidate]:
    """Candidate twins (left component i, right component j, disparity d): every local maximum over d of
    the agreeing rows of a component pair (smoothed over +-1 px) holding ``min_rows`` rows (one pair of
    components can hold two twins at different disparities: merged outlines); ``d_min`` is the smallest
    disparity searched, px. A candidate's votes are those of its key and of the keys +-1 beside it, which
    are neighbours in the sorted distinct keys: one run of the sorted votes (an image of noise makes 10^5
    candidates: their boxes come from each key's, not from a loop over the votes)."""
    table = _candidate_table(ev, d_min)
    if table is None:
        return []
    keys, scores, box, (first, last), (order, starts), span = table
    n_lab = ev.px.n_labels
    pk = keys // span
    cols = (pk // n_lab).tolist(), (pk % n_lab).tolist(), (keys % span + d_min - 1).tolist()
    runs = zip(starts[first].tolist(), starts[last + 1].tolist(), strict=True)
    return [Candidate(i, j, d, order[s:e], score, (b[0], b[1], b[2], b[3]))
            for i, j, d, (s, e), score, b in zip(*cols, runs, scores.tolist(), box.tolist(), strict=True)]


def _candidate_table(ev: Evidence, d_min: int):
    """:func:`_candidates` as arrays (None without any): keys and rows (M,), boxes (M, 4) (u0, v0, u1, v1),
    (first, last) distinct key of each one's votes, (vote order, each distinct key's start), key span."""
    px, p = ev.px, ev.p
    keys, scores, (order, uk, starts), span = _peaks(ev, d_min)
    if not len(keys):
        return None
    at = np.searchsorted(uk, keys)                           # every peak's key is a distinct key
    first = np.where((at > 0) & (uk[np.maximum(at - 1, 0)] == keys - 1), at - 1, at)
    last = np.where((at + 1 < len(uk)) & (uk[np.minimum(at + 1, len(uk) - 1)] == keys + 1), at + 1, at)
    u, v = px.u[p[order]], px.v[p[order]]
    lo = [np.minimum.reduceat(a, starts[:-1]) for a in (u, v)]        # each key's box
    hi = [np.maximum.reduceat(a, starts[:-1]) for a in (u, v)]
    box = np.column_stack([np.minimum(np.minimum(m[first], m[at]), m[last]) for m in lo]
                          + [np.maximum(np.maximum(m[first], m[at]), m[last]) for m in hi])
    return keys, scores, box, (first, last), (order, starts), span


class _Neighbours:
    """Which candidates support which: candidate k supports candidate m when their disparities differ by at
    most 2 px and their boxes come within ``support_px`` of each other (the same object's other edges); not
    itself. Read one candidate at a time (an image of noise makes 10^5 candidates: no K x K table)."""

    def __init__(self, cands: list[Candidate], support_px: int):
        self.d = np.array([c.d for c in cands])
        self.box = np.array([c.box for c in cands], dtype=float).reshape(-1, 4)
        self.reach = support_px

    def of(self, k: int) -> np.ndarray:
        """(K,) bool: the candidates candidate ``k`` supports."""
        b, box, r = self.box[k], self.box, self.reach
        near = ((np.abs(self.d - self.d[k]) <= 2) & (box[:, 0] <= b[2] + r) & (box[:, 2] >= b[0] - r)
                & (box[:, 1] <= b[3] + r) & (box[:, 3] >= b[1] - r))
        near[k] = False
        return near


def _beyond_chance(ev: Evidence, c: Candidate, chance: Chance, reach: int) -> bool:
    """Whether candidate ``c`` may stand as a twin: backed by an accepted pair of its object (its rank holds
    their rows) where chance makes none as strong within ``reach`` px at one disparity
    (:meth:`~psvs.match.chance.Chance.backed_beyond_chance`), or alone, beyond chance's level for one pair
    (:attr:`~psvs.match.chance.Chance.pair_level_rows`, read on the very statistic ``c.rows`` is); never when
    either of its edges twins as strongly or more, beyond chance, at a lag below the range
    (:meth:`~psvs.match.chance.Chance.twin_elsewhere`)."""
    if chance.twin_elsewhere(ev.p[c.votes], ev.q[c.votes], c.rows):
        return False                      # its edge twins as well outside the range: another edge's view
    if c.rank > c.rows and chance.backed_beyond_chance(c.rows, c.box, reach):
        return True
    return c.rows > chance.pair_level_rows


def _strong_enough(ev: Evidence, claims: Claims, c: Candidate, kept: np.ndarray, longest: int,
                   chance: Chance) -> bool:
    """Whether the edge map alone settles candidate ``c``: its agreeing pixels ``kept`` (in runs, the
    longest spanning ``longest`` rows) cover enough rows of the smaller of its two edges' free pixels, or
    one long stretch; a candidate no accepted neighbour supports needs ``standalone_rows`` rows and to stand
    beyond chance by itself (:func:`_beyond_chance`)."""
    prm = ev.params
    agree = n_rows(ev.px.v[kept])                           # distinct agreeing rows
    rows_i, rows_j = claims.free_rows(c.i), claims.free_rows(c.j)
    # a merged outline (both views in one component) pairs with itself: half is left, half right
    smaller = rows_i / 2 if c.i == c.j else min(rows_i, rows_j)
    # an edge backed by no accepted pair at its disparity nearby stands beyond chance by itself
    need = prm.min_rows if c.rank > c.rows else prm.standalone_rows
    settled = not (agree < need or (agree < prm.min_fraction * smaller and longest < prm.long_run_rows))
    return settled and _beyond_chance(ev, c, chance, prm.support_px)


def _first_pass(ev: Evidence, claims: Claims, cands: list[Candidate], chance: Chance) -> list[Candidate]:
    """Accept candidates the edge map settles, best supported first; return those it does not settle
    (with a grey image, and not a merged outline: left for the second pass), in the order they came.

    A candidate's support is its own agreeing rows plus the rows of the accepted candidates near it
    (:class:`_Neighbours`): each acceptance raises the rank of the remaining candidates it supports, and the
    next candidate is the remaining one of highest rank (the first such on ties)."""
    later: list[Candidate] = []
    if not cands:
        return later
    rows = np.array([c.rows for c in cands])
    near = _Neighbours(cands, ev.params.support_px)
    rank = rows.copy()
    remaining = np.ones(len(cands), dtype=bool)
    while remaining.any():
        k = int(np.argmax(np.where(remaining, rank, -np.inf)))
        remaining[k] = False
        c = replace(cands[k], rank=float(rank[k]))
        votes = c.votes[claims.free[ev.p[c.votes]] & claims.free[ev.q[c.votes]]]
        runs = long_runs(ev.px, ev.p[votes], ev.params.min_run)
        kept, longest = joined(runs), max((row_span(ev.px, r) for r in runs), default=0)
        if not _strong_enough(ev, claims, c, kept, longest, chance):
            if ev.polarity is not None and c.i != c.j:
                later.append(c)
        elif claims.accept(c, kept, votes):
            rank += near.of(k) * rows[k]
    return later


def _partly_hidden_twin(ev: Evidence, claims: Claims, c: Candidate,
                        index: tuple) -> tuple[np.ndarray, np.ndarray] | None:
    """The twin of left edge ``c.i`` at disparity ``c.d`` from its visible pieces, wherever they are.

    Where one object's view overlaps another object's view, the binary edge map keeps only part of its
    twin's outline, and that part is merged with the other object's outline (or its inner contour). The
    visible pieces are gathered over *all* components at ``c.d`` +-1 px (except pixels already claimed for
    the right view); they must agree on at least ``min_rows`` rows in stretches of ``min_run`` rows. The
    rest of the twin must be explained: on at least ``standalone_rows`` rows of edge ``c.i``, and on
    ``seen_fraction`` of its rows where saturation does not blind the grey image, the grey image steps the
    same way at the twin's column (:func:`psvs.match.grey_steps.twin_step_seen`), whether the edge map
    kept that piece or lost it on the bright overlap.

    ``index`` holds the votes and the pixels by component, each as :func:`_by_label` gives them. Returns
    (agreeing left pixels, free pixels of the components holding the twin's pieces) as indices into
    ``ev.px``, or None.
    """
    px, p, q, prm = ev.px, ev.p, ev.q, ev.params
    free, explained, claimed = claims.free, claims.explained, claims.claimed
    (vote_order, vote_start), (pix_order, pix_start) = index
    i, ds = c.i, c.d
    sel = vote_order[vote_start[i]:vote_start[i + 1]]
    sel = sel[(np.abs(ev.d[sel] - ds) <= 1) & free[p[sel]] & ~explained[p[sel]] & free[q[sel]]
              & (px.label[q[sel]] != i)]
    sel = sel[~claimed[1, px.v[q[sel]], px.u[q[sel]] + claims.pad]]
    if n_rows(px.v[p[sel]]) < prm.min_rows:
        return None
    kept = joined(long_runs(px, p[sel], prm.min_run))
    if n_rows(px.v[kept]) < prm.min_rows:
        return None
    left = pix_order[pix_start[i]:pix_start[i + 1]]
    left = left[free[left] & ~explained[left]]                  # not already explained by an accepted pair
    seen, blind = twin_step_seen(ev.steps, px, left, ds, prm.tol_px, prm.polarity_level, claimed[1])
    seen_rows = n_rows(px.v[left[seen]])
    blind_rows = n_rows(px.v[left]) - n_rows(px.v[left[~blind]])    # rows with all their twins blind
    if seen_rows < prm.standalone_rows or seen_rows < prm.seen_fraction * (n_rows(px.v[left]) - blind_rows):
        return None
    in_kept = np.zeros(len(px.u), dtype=bool)
    in_kept[kept] = True
    holders = np.zeros(px.n_labels, dtype=bool)
    holders[px.label[q[sel][in_kept[p[sel]]]]] = True
    return kept, np.flatnonzero(free & holders[px.label])


def _second_pass(ev: Evidence, claims: Claims, later: list[Candidate], chance: Chance) -> None:
    """Once the edge map has settled what it can (so this pass never takes a pixel a first-pass pair
    needed), accept the candidates ``later`` whose twin is partly hidden on, or merged with, another
    object's view (:func:`_partly_hidden_twin`), if they stand beyond chance as the first pass deferred them
    (:func:`_beyond_chance`). A left edge and disparity found wanting is not
    tried again until some pair is accepted."""
    px, prm = ev.px, ev.params
    index = (by_label(px.label[ev.p], px.n_labels), by_label(px.label, px.n_labels))
    tried: set[tuple[int, int]] = set()
    for c in later:
        if (c.i, c.d) in tried or claims.free_rows(c.i) < prm.standalone_rows:
            continue
        tried.add((c.i, c.d))
        stands = _beyond_chance(ev, c, chance, prm.support_px)
        hidden = _partly_hidden_twin(ev, claims, c, index) if stands else None
        if hidden is not None and claims.accept(c, hidden[0], c.votes, hidden[1]):
            tried.clear()


def _unmatched(px: EdgePixels, claims: Claims) -> list[Unmatched]:
    """The components not mostly paired (or explained): stray pixels of a paired edge are not an unmatched
    edge. Each with its free pixels' count and bounding box."""
    sizes = np.bincount(px.label, minlength=px.n_labels)
    paired = np.bincount(px.label[~claims.free | claims.explained], minlength=px.n_labels)
    todo = np.flatnonzero(paired < 0.5 * sizes)          # each holds free pixels: more than half of its own
    if not len(todo):
        return []
    order, start = by_label(px.label[claims.free], px.n_labels)
    cuts = np.column_stack([start[todo], start[todo + 1]]).ravel()    # each component's run, and the gap after
    ends = []
    for a in (px.u[claims.free][order], px.v[claims.free][order]):
        a = np.append(a, 0)                                            # a run may end at the last pixel
        ends += [np.minimum.reduceat(a, cuts)[::2], np.maximum.reduceat(a, cuts)[::2]]
    u0, u1, v0, v1 = (e.tolist() for e in ends)
    counts = (start[todo + 1] - start[todo]).tolist()
    return [Unmatched(lab, n, tuple(box)) for lab, n, *box in zip(todo.tolist(), counts, u0, v0, u1, v1, strict=True)]


def match_auto(edges: np.ndarray, disparity_range_px: tuple[float, float], *, params: AutoParams = AutoParams(),
               grey: np.ndarray | None = None, rect=None) -> AutoMatch:
    """Pair all edges of an (H, W) bool edge map with their twins.

    Parameters
    ----------
    edges : ndarray of bool, shape (H, W)
    disparity_range_px : (d_min, d_max)
        Disparities u_l - u_r the rig can produce in its working range, px.
    params : AutoParams
        The tuning (rows a twin must agree on, tolerances, support distance, grey-image checks).
    grey : ndarray, shape (H, W), optional
        The (filtered) grey image the edges came from. When given, a vote needs both pixels to step the
        same way across the edge (``params.polarity_level``), and a second pass pairs the left edges whose
        twin the edge map keeps only in pieces (``params.seen_fraction``).
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
    if not isinstance(params, AutoParams):
        raise TypeError(f"params must be an AutoParams, got {type(params).__name__}")
    ev, pad = _evidence(edges, (d_min, d_max), params, grey, rect)
    claims = Claims(ev, pad)
    cands = _candidates(ev, int(d_min)) if len(ev.p) else []
    chance = _chance(ev, np.array([c.rows for c in cands]), d_min, d_max, elsewhere=True)
    if chance.answered:
        later = _first_pass(ev, claims, cands, chance)
        _second_pass(ev, claims, later, chance)
    pairs = [] if claims.rows.refuses else claims.pairs
    return AutoMatch(pairs, _unmatched(ev.px, claims), ev.px, chance, claims.rows)


def image_chance(edges: np.ndarray, disparity_range_px: tuple[float, float], *, params: AutoParams = AutoParams(),
                 grey: np.ndarray | None = None, rect=None, px: EdgePixels | None = None,
                 elsewhere: bool = False) -> Chance:
    """Whether the image holds twins at all: :func:`match_auto`'s candidates against chance
    (:mod:`psvs.match.chance`), without pairing them; arguments as :func:`match_auto`'s, and ``px`` the edge
    map's :func:`~psvs.match.edges.edge_pixels` (under ``rect``) when the caller has them. The paper's seeded
    algorithm asks it before it takes an edge (psvs.match.correspondence, psvs.live.tracker); with
    ``elsewhere`` it also reads the twins below the range a seed's pair must not contradict
    (:func:`psvs.match.chance.seed_pair_stands`)."""
    d_min, d_max = disparity_range_px
    ev, _ = _evidence(edges, (d_min, d_max), params, grey, rect, with_steps=False, px=px)
    return _chance(ev, _peaks(ev, int(d_min))[1] if len(ev.p) else np.zeros(0), d_min, d_max, elsewhere)


def _evidence(edges, d_range, params: AutoParams, grey, rect, with_steps: bool = True,  # noqa: PLR0913
              px: EdgePixels | None = None) -> tuple[Evidence, int]:
    """The :class:`Evidence` of an edge map at disparities ``d_range`` and the claims' column padding; the
    grey image's step image only ``with_steps`` (the pairing's second pass reads it, chance does not); ``px``
    the map's edge pixels if already labelled."""
    px = edge_pixels(edges, rect) if px is None else px
    pol = steps = None
    pad = int(np.ceil(d_range[1] + params.tol_px)) + 1
    if grey is not None and len(px.u):
        grey = np.asarray(grey, dtype=np.float64)
        pol = polarity(grey, px, params.polarity_level)
        steps = step_image(grey, pad) if with_steps else None
    return Evidence(px, *_polar_votes(px, pol, *d_range), pol, steps, params), pad


def _polar_votes(px: EdgePixels, pol: np.ndarray | None, d_min: float, d_max: float):
    """The row votes (p, q, d) at disparities ``d_min..d_max`` whose two pixels do not step opposite ways
    (``pol``: each pixel's polarity; None: every vote)."""
    p, q, d = row_votes(px, d_min, d_max)
    if pol is not None and len(p):
        ok = (pol[p] == pol[q]) | (pol[p] == 0) | (pol[q] == 0)
        p, q, d = p[ok], q[ok], d[ok]
    return p, q, d


def _chance(ev: Evidence, rows: np.ndarray, d_min: float, d_max: float, elsewhere: bool = False) -> Chance:
    """How the working range's candidates (their agreeing ``rows`` (M,)) stand against the candidates the
    same votes make at disparities the range cannot produce (:mod:`psvs.match.chance`); with ``elsewhere``,
    also the twins below the range a pairing must not contradict (:func:`_elsewhere`)."""
    lu, ru = ev.px.left_uv[0], ev.px.right_uv[0]
    width = int(max(lu.max(), ru.max())) + 1 if len(lu) else 0
    bands = null_bands(d_min, d_max, width)
    null, boxes, lags = [np.zeros(0)], [np.zeros((0, 4))], [np.zeros(0)]
    for a, b in bands:
        p, q, d = _polar_votes(ev.px, ev.polarity, a, b)
        table = _candidate_table(Evidence(ev.px, p, q, d, ev.polarity, None, ev.params), int(a)) if len(p) else None
        if table is not None:
            null.append(table[1])
            boxes.append(table[2])
            lags.append((table[0] % table[5] + int(a) - 1).astype(float))
    null = np.concatenate(null)
    strongest = float(rows.max(initial=0.0))
    if not bands:                # nowhere to read chance: nothing is answered
        return Chance(strongest, math.inf, 0.0, 0, len(rows), ())
    level = chance_level(null, len(rows), ev.params.min_rows)
    below = _elsewhere(ev, d_min) if elsewhere and bands[0][0] > d_max else None
    candidates = NullCandidates(null, np.concatenate(boxes), bands, np.concatenate(lags))
    return Chance(strongest, level, float(null.max(initial=0.0)), len(null), len(rows), tuple(bands),
                  pair_level(null, rows, ev.params.min_rows), candidates, below)


def _elsewhere(ev: Evidence, d_min: float) -> Elsewhere | None:
    """The candidates the same votes make at lags below the range, from half ``d_min`` up to ``d_min`` less
    :data:`~psvs.match.chance.GAP_PX` (depths up to about twice the far limit): each edge pixel's strongest as
    left and as right pixel of a vote (:class:`~psvs.match.chance.Elsewhere`); None when that band is narrower
    than :data:`~psvs.match.chance.MIN_BAND_PX`. Shorter lags are left out: there an edge agrees with its own
    view's next edge (both sides of a thin line, a texture's short repeat) as well as with a far twin, as
    the dense engine's short repeats (psvs.dense.elsewhere)."""
    a, b = max(GAP_PX, 0.5 * d_min), d_min - GAP_PX
    if b - a < MIN_BAND_PX:
        return None
    n = len(ev.px.u)
    rows, lags = np.zeros((2, n)), np.zeros((2, n))
    p, q, d = _polar_votes(ev.px, ev.polarity, a, b)
    table = _candidate_table(Evidence(ev.px, p, q, d, ev.polarity, None, ev.params), int(a)) if len(p) else None
    if table is not None:
        keys, scores, _, (first, last), (order, starts), span = table
        lo, hi = starts[first], starts[last + 1]                  # each candidate's run of the sorted votes
        length = hi - lo
        run = np.repeat(lo - np.cumsum(length) + length, length) + np.arange(int(length.sum()))
        votes, score = order[run], np.repeat(scores, length)
        lag = np.repeat((keys % span + int(a) - 1).astype(float), length)
        for side, pix in enumerate((p[votes], q[votes])):
            by = np.lexsort((score, pix))                          # by pixel, the strongest last
            last_of = np.append(pix[by][1:] != pix[by][:-1], True)
            rows[side, pix[by][last_of]] = score[by][last_of]
            lags[side, pix[by][last_of]] = lag[by][last_of]
    keys = [uv[1].astype(np.int64) * (1 << 32) + uv[0].astype(np.int64)
            for uv in (np.rint(ev.px.left_uv), np.rint(ev.px.right_uv))]
    return Elsewhere(rows[0], rows[1], lags[0], lags[1], (a, b), keys[0], keys[1])
