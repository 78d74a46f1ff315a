"""Which blob of a complex image is which view's, and whose twin: pairing through the rig's epipolar geometry.

Every feature of a target appears twice, once per view. Its left-view image at p sees a ray; the points
of that ray over the working depths project into the right view along a known curve, the epipolar curve of
p (:func:`psvs.optics.trace.trace_pixels`, :func:`psvs.optics.project.project_points`). The twin of a
left-view feature lies on that curve, at a disparity u_l - u_r > 0 in the working range's. A build's mirrors
differ from its nominal design by fractions of a degree, which add up along the two paths, so the curve is
searched in a band of :data:`BAND_DEG` (in angle through the lens) on either side and along it.

That test alone cannot tell a disc's twin from a neighbour of its twin along the same curve (a card
wider than its disparity puts several discs of the other view on the curve). A target is one plane: its
twins sit one smooth shift apart. So a pairing is grown from each candidate pair over the blobs' image
neighbourhoods, each new pair's shift within :data:`SHIFT_TOL` of the shift of the pair it was reached from
(its neighbour on the card), every blob used once; the pairing that explains the most blobs is the target's
(a pairing one column off leaves the outer column of each view unpaired).
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np
from scipy.spatial import cKDTree

from psvs.optics.project import epipolar_curves_px
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels

#: How far (degrees through the lens) a build may put a twin off its nominal epipolar curve. A mirror tilted
#: b out of vertical turns its view by 2 b; four mirrors glued up to 0.3 deg off (issue 40's builds) put one
#: view's rows up to 2.4 deg off the other's. With 1 deg a fresh sweep draw's copies of its card, 35 px (one row
#: of discs) apart, paired one row off in every view (tests/targets/test_detect.py). Wider costs 30 % of a
#: view's detection time; the pairing that explains the most discs still wins.
BAND_DEG = 2.5
#: A pair's shift may differ from its neighbour's by this share of the two blobs' distance.
SHIFT_TOL = 0.3
#: The working depths (mm) whose epipolar curve is searched (a build's depths may be far off the design's).
SEARCH_DEPTHS_MM = (250.0, 5000.0)


def band_px(rig: Rig) -> float:
    """:data:`BAND_DEG` in px of this camera (its focal length over its pitch)."""
    c = rig.camera
    return math.tan(math.radians(BAND_DEG)) * c.focal_length_mm / min(c.pixel_pitch_mm)


def twin_distances_px(centres_px: np.ndarray, rig: Rig, near_mm: float, far_mm: float,
                      samples: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """The one twin test of psvs's targets: (across, beyond), each (N, N) px, for centre a as a left-view
    image and centre b as its right-view twin. ``across[a, b]`` is how far b lies from a's epipolar curve
    (the right-view image of a's ray, :func:`psvs.optics.project.epipolar_curves_px`, continued straight
    past its ends) and ``beyond[a, b]`` how far along it b lies outside the part between depths near_mm and
    far_mm (0 inside: the disparity is in the working range). inf where a's ray is vignetted or nothing of
    it projects. The ray is sampled evenly in disparity (1/(Z - z_v))."""
    c = np.asarray(centres_px, dtype=float).reshape(-1, 2)
    n = len(c)
    rays = trace_pixels(c, rig, "left")
    zv = rig.virtual_z_mm
    z = zv + 1.0 / np.linspace(1.0 / (near_mm - zv), 1.0 / (far_mm - zv), samples)
    across, beyond = np.full((n, n), np.inf), np.full((n, n), np.inf)
    reach = 10.0 * sum(rig.camera.image_size_px)                     # the straight continuations, px
    live = np.flatnonzero(rays.valid)
    cu, cv = c[:, :1], c[:, 1:]                                                     # (N, 1) each
    curves, seen = epipolar_curves_px(rays.origins_mm[live], rays.dirs[live], z, rig)
    for a, uv, ok in zip(live, curves, seen, strict=True):
        uv = uv[ok]
        if len(uv) < 2:
            continue
        t0, t1 = uv[0] - uv[1], uv[-1] - uv[-2]
        uv = np.vstack([uv[0] + reach * t0 / np.linalg.norm(t0), uv, uv[-1] + reach * t1 / np.linalg.norm(t1)])
        p, ab = uv[:-1], np.diff(uv, axis=0)                                        # (S, 2) segments
        ru, rv = cu - p[:, 0], cv - p[:, 1]                                         # (N, S) each
        s = np.clip((ru * ab[:, 0] + rv * ab[:, 1]) / np.maximum((ab * ab).sum(1), 1e-300), 0.0, 1.0)
        ru -= s * ab[:, 0]
        rv -= s * ab[:, 1]
        d = np.sqrt(ru * ru + rv * rv)
        k = d.argmin(axis=1)
        rows = np.arange(n)
        across[a] = d[rows, k]
        sk = s[rows, k]
        beyond[a] = np.where(k == 0, (1.0 - sk) * reach, np.where(k == len(ab) - 1, sk * reach, 0.0))
    np.fill_diagonal(across, np.inf)
    return across, beyond


def twin_candidates(points_px: np.ndarray, rig: Rig, depths_mm=SEARCH_DEPTHS_MM) -> list[list[int]]:
    """For each point (n, 2) px taken as a left-view image, the other points that may be its right-view
    twin: within :func:`band_px` of its epipolar curve over ``depths_mm`` (through ``rig``, across the
    curve and along it: :func:`twin_distances_px`), left of it."""
    p = np.asarray(points_px, dtype=float).reshape(-1, 2)
    across, beyond = twin_distances_px(p, rig, *depths_mm)
    near = (np.hypot(across, beyond) <= band_px(rig)) & (p[None, :, 0] < p[:, None, 0])
    return [np.flatnonzero(row).tolist() for row in near]


def pair_twins(points_px: np.ndarray, reach_px: np.ndarray, rig: Rig, sizes_px: np.ndarray | None = None,
               prefer=None, shared: np.ndarray | None = None, weights: np.ndarray | None = None,
               shift_px: np.ndarray | None = None) -> np.ndarray:
    """The pairing of points into (left, right) twins that explains the most of them.

    Parameters
    ----------
    points_px : ndarray, shape (n, 2)
        The features' image positions in the complex image (both views mixed), px.
    reach_px : ndarray, shape (n,)
        How far a feature's nearest neighbours on the target lie in the image (at most), px.
    rig : Rig
        The nominal design (its epipolar geometry; a build may be degrees off, :data:`BAND_DEG`).
    sizes_px : ndarray, shape (n,), optional
        The features' sizes: twins differ by less than a factor 1.4.
    prefer : callable, optional
        pairs (m, 2) -> cost: of pairings that explain nearly as many points (:data:`NEAR_TIE`), the
        cheapest is taken (where a column of each view merges with the other's, a pairing one column off
        explains as many or more); without it, the largest.
    weights : ndarray, shape (n,), optional
        How much each point counts (a pair counts as its lesser point): a blob split off a larger dark
        region may be a fragment of something else (the dark gap between the two copies of a card), so it
        counts less than a clean disc. The pairing of the most weight wins. Default: 1 each.
    shift_px : ndarray, shape (n, 2), optional
        The least and most a point's twin may lie to its left (u_l - u_r, px), e.g. from its own size
        (:func:`psvs.targets.detect.disparity_per_size`): the epipolar curve over the search depths
        alone also reaches a neighbour of the same view (one step of the card) at the far depths.
    shared : ndarray, shape (n,) bool, optional
        Points that may be used twice, once as a left image and once as a right one: two discs of the two
        views merged into one blob (where columns of the two views coincide, a pairing one column off
        would otherwise explain more discs than the true one).

    Returns
    -------
    pairs : ndarray, shape (m, 2) int
        Indices (left, right) into ``points_px``; m = 0 when no feature has a twin.
    """
    pts = np.asarray(points_px, float)
    shared = np.zeros(len(pts), bool) if shared is None else np.asarray(shared, bool)
    cands = twin_candidates(pts, rig)
    if sizes_px is not None:
        s = np.asarray(sizes_px, float)
        cands = [[j for j in c if 1 / 1.4 < s[i] / s[j] < 1.4] for i, c in enumerate(cands)]
    if shift_px is not None:
        lo, hi = np.asarray(shift_px, float).T
        cands = [[j for j in c if lo[i] <= pts[i, 0] - pts[j, 0] <= hi[i]] for i, c in enumerate(cands)]
    tree = cKDTree(pts)
    near = [tree.query_ball_point(p, r) for p, r in zip(pts, reach_px, strict=True)]
    grown_sets: list[list[tuple[int, int]]] = []
    seen: set[tuple[int, int]] = set()
    as_tuples = [tuple(p) for p in pts.tolist()]
    for i, c in enumerate(cands):
        for j in c:
            if (i, j) not in seen:
                grown = _grow(i, j, as_tuples, cands, near, shared)
                seen.update(grown)
                grown_sets.append(grown)
    if not grown_sets:
        return np.zeros((0, 2), int)
    step = float(np.median(reach_px)) / REACH_OVER_STEP
    w = np.ones(len(pts)) if weights is None else np.asarray(weights, float)

    def score(p):
        return float(np.minimum(w[p[:, 0]], w[p[:, 1]]).sum()) if len(p) else 0.0

    most = max(score(np.array(g)) for g in grown_sets)
    found = []
    for g in grown_sets:
        pairs = np.array(g, dtype=int).reshape(-1, 2)
        if score(pairs) >= NEAR_TIE * most - 1.0:           # repairing may gain a pair or two
            found.append(_repair(pts, pairs, cands, step, shared) if len(pairs) >= 6 else pairs)
    most = max(score(p) for p in found)
    tied = [p for p in found if score(p) >= NEAR_TIE * most]
    if prefer is None or len(tied) == 1:
        return max(tied, key=len)
    return min(tied, key=prefer)                 # a pose can make two pairings equally large


#: Pairings explaining at least this share of the most explained are told apart by ``prefer`` (only exact
#: ties: the nominal rig's sizes may be a fifth off on a build, as much as a pairing one column off).
NEAR_TIE = 1.0


#: How much farther than a target's step its neighbours are looked for (:func:`pair_twins`' ``reach_px``).
REACH_OVER_STEP = 1.6
#: A twin lies within this share of the target's step of where the pairing's shift model puts it.
MODEL_TOL = 0.2


def _shift_model(p: np.ndarray, shift: np.ndarray):
    """Least-squares shift (left - right, px) as a function of the left position: affine in (u, v) (a
    plane's disparity is affine in a pinhole view), quadratic with 12 or more pairs (the lens bends it a
    little). Returns a function (n, 2) -> (n, 2)."""
    c = p.mean(axis=0)
    s = max(float(np.ptp(p, axis=0).max()), 1.0)
    quadratic = len(p) >= 12

    def terms(x):
        x = (x - c) / s
        t = [np.ones(len(x)), x[:, 0], x[:, 1]]
        if quadratic:
            t += [x[:, 0] ** 2, x[:, 0] * x[:, 1], x[:, 1] ** 2]
        return np.column_stack(t)

    coef, *_ = np.linalg.lstsq(terms(p), shift, rcond=None)
    return lambda x: terms(x) @ coef


def _inliers(p: np.ndarray, shift: np.ndarray, tol: float) -> np.ndarray:
    """The pairs an affine shift model explains within ``tol`` px: RANSAC over triples (seeded: the same
    image gives the same answer), the largest consensus."""
    rng = np.random.default_rng(0)
    triples = np.array([rng.choice(len(p), 3, replace=False) for _ in range(200)])           # (T, 3)
    q = p[triples]                                                                           # (T, 3, 2)
    d = q[:, 1:] - q[:, :1]
    ok = np.abs(d[:, 0, 0] * d[:, 1, 1] - d[:, 0, 1] * d[:, 1, 0]) >= 1e-6    # not collinear
    if not ok.any():
        return np.zeros(len(p), bool)
    triples, q = triples[ok], q[ok]
    # each triple's affine shift model (1, u, v) through its three pairs exactly, all triples at once
    coef = np.linalg.solve(np.concatenate([np.ones(q.shape[:2] + (1,)), q], axis=2), shift[triples])
    pred = np.concatenate([np.ones((len(p), 1)), p], axis=1) @ coef                         # (T, N, 2)
    inside = np.hypot(*np.moveaxis(shift[None] - pred, 2, 0)) <= tol                        # (T, N)
    return inside[int(np.argmax(inside.sum(axis=1)))]


def _repair(pts: np.ndarray, pairs: np.ndarray, cands: list[list[int]], step_px: float,
            shared: np.ndarray) -> np.ndarray:
    """Pair again with the grown pairing's smooth shift model: every candidate pair within
    :data:`MODEL_TOL` steps of the model, taken best first, each point used once. The growth is greedy (a
    column of the other view a few px off the true one may be taken on the way); the model, fitted to the
    pairs one plane's shift explains (RANSAC), is not."""
    tol = MODEL_TOL * step_px
    p, shift = pts[pairs[:, 0]], pts[pairs[:, 0]] - pts[pairs[:, 1]]
    keep = _inliers(p, shift, tol)
    if keep.sum() < 6:
        return pairs
    model = _shift_model(p[keep], shift[keep])
    pred = pts - model(pts)                              # where each point's twin lies, were it a left one
    edges = sorted((float(np.linalg.norm(pts[j] - pred[i])), i, j) for i, c in enumerate(cands) for j in c)
    used = _Roles(shared)
    out = []
    for cost, i, j in edges:
        if cost > tol:
            break
        if used.free(i, "left") and used.free(j, "right"):
            used.take(i, j)
            out.append((i, j))
    return np.array(out, dtype=int).reshape(-1, 2)


class _Roles:
    """Which points a pairing has used, as a left and as a right image: a point is used once, except a
    ``shared`` one (two discs merged into one blob), which may be one view's disc and the other's twin."""

    def __init__(self, shared: np.ndarray):
        self.shared, self.left, self.right = shared, set(), set()

    def free(self, k: int, role: str) -> bool:
        mine, other = (self.left, self.right) if role == "left" else (self.right, self.left)
        return k not in mine and (k not in other or bool(self.shared[k]))

    def take(self, i: int, j: int) -> None:
        self.left.add(i)
        self.right.add(j)


def _grow(i: int, j: int, pts: list[tuple[float, float]], cands: list[list[int]], near: list[list[int]],
          shared: np.ndarray) -> list[tuple[int, int]]:
    """The pairs reached from (i, j) over image neighbours of the left members, each pair's shift
    (left - right) within :data:`SHIFT_TOL` of the neighbour's it was reached from; every point used once
    (a ``shared`` one once per role). ``pts``: the points as (u, v) tuples, px (scalar arithmetic: this loop
    runs over every candidate pair of a card's hundreds of blobs, for every card view)."""
    left, right, two = {i}, {j}, shared.tolist()       # _Roles's sets, inlined: the inner loop's every step
    pairs = [(i, j)]
    queue = deque(pairs)
    while queue:
        a, b = queue.popleft()
        (ua, va), (ub, vb) = pts[a], pts[b]
        su, sv = ua - ub, va - vb
        for k in near[a]:
            if k in left or (k in right and not two[k]):
                continue
            uk, vk = pts[k]
            best, err = -1, SHIFT_TOL * math.hypot(uk - ua, vk - va)
            for m in cands[k]:
                if m == k or m in right or (m in left and not two[m]):
                    continue
                um, vm = pts[m]
                e = math.hypot(uk - um - su, vk - vm - sv)
                if e <= err:
                    best, err = m, e
            if best >= 0:
                left.add(k)
                right.add(best)
                pairs.append((k, best))
                queue.append((k, best))
    return pairs
