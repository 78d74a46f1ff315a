"""Label the image of a planar lattice of points (a circle grid's discs) with their places on the target.

The points of one view are labelled with integer lattice coordinates by growing from the point nearest
their middle: its two shortest non-parallel neighbour vectors span the lattice there, and each labelled
point's four lattice neighbours are looked for where the labels' fitted map (an affine map, then a
homography once enough points are labelled) says they lie, from that point (so a lens's distortion, which
bends the grid slowly, only matters over one step). The labels are then placed on the target's own lattice
by one of its rotations and a translation that puts every labelled point on a disc of the target; a card
seen from the front in both views is never mirrored (each view passes two mirrors), so the labels' axes
are taken right-handed in the image, as the card's are. Points the growth does not reach are left out.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree

#: A lattice neighbour is accepted this close to where it is predicted, as a share of the step.
STEP_TOL = 0.3


def _basis(pts: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The two shortest non-parallel neighbour vectors at the seed, right-handed in the image (u, v)."""
    d = pts - pts[seed]
    n = np.linalg.norm(d, axis=1)
    order = [k for k in np.argsort(n) if n[k] > 0]
    if not order:
        return None
    a = d[order[0]]
    for k in order[1:]:
        cos = abs(d[k] @ a) / (n[k] * np.linalg.norm(a))
        if cos < 0.5:
            b = d[k]
            return (a, b) if a[0] * b[1] - a[1] * b[0] > 0 else (a, -b)
    return None


def label_lattice(points_px: np.ndarray) -> np.ndarray:
    """Integer lattice coordinates (n, 2) of image points (n, 2) px of one view; (-9999, -9999) where the
    growth did not reach a point. The axes follow the seed's two shortest neighbour vectors."""
    pts = np.asarray(points_px, float)
    n = len(pts)
    labels = np.full((n, 2), -9999, int)
    if n < 3:
        return labels
    seed = int(np.argmin(np.linalg.norm(pts - np.median(pts, axis=0), axis=1)))
    basis = _basis(pts, seed)
    if basis is None:
        return labels
    a, b = basis
    tree = cKDTree(pts)
    where = {(0, 0): seed}
    labels[seed] = (0, 0)
    grew = True
    while grew:
        grew = False
        model = _model(where, pts, pts[seed], a, b)
        for (p, q), k in list(where.items()):
            for step in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                lab = (p + step[0], q + step[1])
                if lab in where:
                    continue
                delta = model(np.array([lab], float))[0] - model(np.array([(p, q)], float))[0]
                guess = pts[k] + delta
                dist, m = tree.query(guess)
                if dist <= STEP_TOL * np.linalg.norm(delta) and labels[m, 0] == -9999:
                    where[lab] = int(m)
                    labels[m] = lab
                    grew = True
    return labels


def _model(where: dict, pts: np.ndarray, origin: np.ndarray, a: np.ndarray, b: np.ndarray):
    """labels (k, 2) -> image (k, 2): a homography fitted to the labelled points when there are enough
    of them off one line, else the seed's affine map."""
    labs = np.array(list(where.keys()), float)
    if len(labs) >= 6 and np.linalg.matrix_rank(labs - labs.mean(axis=0), tol=1e-6) == 2:
        H, _ = cv2.findHomography(labs, pts[list(where.values())], 0)
        if H is not None:
            return lambda x: cv2.perspectiveTransform(x.reshape(-1, 1, 2), H).reshape(-1, 2)
    return lambda x: origin + x[:, :1] * a + x[:, 1:] * b


#: The four turns of a lattice (det +1): a card's labels may be any of them.
_TURNS = [np.array(m) for m in (((1, 0), (0, 1)), ((0, -1), (1, 0)), ((-1, 0), (0, -1)), ((0, 1), (-1, 0)))]


def place_on_target(labels: np.ndarray, lattice: np.ndarray, to_units: np.ndarray,
                    x_dir_px: np.ndarray) -> tuple[np.ndarray | None, bool]:
    """Each label's index into the target's points (None when no placement puts them all on it), and
    whether that placement is the only one: part of a symmetric grid (a column missing) fits it at several
    places, one taken (the ids are then right up to a shift along the grid, which a calibration does not
    mind: the pose takes it up).

    Parameters
    ----------
    labels : ndarray, shape (n, 2) int
        Lattice labels of one view (:func:`label_lattice`).
    lattice : ndarray, shape (N, 2) int
        The target's points in its own integer units, its point order (e.g. (col, row)).
    to_units : ndarray, shape (2, 2) int
        Maps a label step to target units (columns: the units of the labels' first and second axis).
    x_dir_px : ndarray, shape (2, 2)
        The image directions of the labels' two axes: of several placements, the one whose target +x
        runs closest to the image's +u is taken (a symmetric grid's half turn is otherwise undecided).
    """
    index = {tuple(p): k for k, p in enumerate(np.asarray(lattice).tolist())}
    units = labels @ to_units.T
    best, best_cos, count = None, -np.inf, 0
    for turn in _TURNS:
        c = units @ turn.T
        for t in sorted({tuple(np.array(p) - c[0]) for p in index}):
            ids = [index.get(tuple(x)) for x in (c + t).tolist()]
            if any(k is None for k in ids):
                continue
            # the image direction of the target's +x: solve units(label axes) for it
            m = turn @ to_units                       # label step -> target units
            step = np.linalg.solve(m.astype(float), [1.0, 0.0])
            direction = step @ x_dir_px
            cos = direction[0] / (np.linalg.norm(direction) + 1e-12)
            if cos > best_cos + 1e-9:
                best, best_cos, count = np.array(ids), cos, 1
            elif cos > best_cos - 1e-9:
                count += 1
    return best, count == 1
