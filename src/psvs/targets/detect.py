"""Find a calibration target in both views of one complex image: :func:`detect_target`.

The target is what ``target.toml`` describes (:mod:`psvs.targets.target_file`): a symmetric circle grid,
OpenCV's asymmetric circle grid or a ChArUco board. The answer is each view's points with their ids on the
target (so a capture assistant can use it frame by frame), or a ValueError saying why the image cannot be
read and what to do about it ("hold the card closer", "farther", "turn the card", ...).

Circle grids (docs/calibration.md, "Target kinds"): every dark disc is found, touching discs split apart
(:mod:`psvs.targets.discs`); the discs are paired into twins through the nominal rig's epipolar geometry,
the pairing that explains the most discs winning (:mod:`psvs.targets.twins`), so the card's two views may
interleave; the left view's discs are labelled on the target's lattice (:mod:`psvs.targets.lattice`) and
each twin takes its left disc's label. A disc that touches or nearly touches another, or that another view's
card edge crosses, is kept for the labels but not trusted (``reliable`` False): its centre is biased. A disc
whose rim is read on at least :data:`MIN_RIM_SHARE` of its rays (those running into a neighbour are not
read) on an even ground is trusted, touching or not: on mv1440 renders such discs lie within 0.1 px.
ChArUco boards: :mod:`psvs.targets.charuco`.
"""
from __future__ import annotations

import math

import numpy as np

from psvs._validate import check_grey
from psvs.optics.illumination import flat_field
from psvs.optics.rig import Rig
from psvs.simulate.textures import AsymmetricCircleGrid, CharucoBoard
from psvs.targets.discs import find_discs
from psvs.targets.lattice import label_lattice, place_on_target
from psvs.targets.pattern import MIN_CONTRAST
from psvs.targets.target_points import Target, TargetDetection
from psvs.targets.twins import REACH_OVER_STEP, pair_twins

#: A disc whose surroundings vary more than this (share of its contrast) is not trusted for calibration.
MAX_BACKGROUND_SPREAD = 0.25
#: A disc is trusted when its rim was read on at least this share of its rays (the others ran into a
#: touching disc, or found no clear step).
MIN_RIM_SHARE = 0.75
RIM_RAYS = 64
#: The depths (mm) a hand-held card is looked for at: the disc sizes searched follow from them.
CARD_DEPTHS_MM = (300.0, 2000.0)
#: The smallest disc (px across) located to a tenth of a pixel.
MIN_DISC_PX = 4.0

def detect_target(grey: np.ndarray, target: Target, rig: Rig, depths_mm=CARD_DEPTHS_MM) -> TargetDetection:
    """Both views of ``target`` in one complex image, through the nominal ``rig``'s geometry.

    Parameters
    ----------
    grey : ndarray, shape (H, W)
        The complex image (uint8, or float in [0, 1]).
    target : CircleGrid, AsymmetricCircleGrid or CharucoBoard
    rig : Rig
        The nominal design (a build may differ from it by a fraction of a degree).
    depths_mm : (float, float)
        Where the target may be: the sizes its features are looked for at.

    Returns
    -------
    TargetDetection

    Raises
    ------
    ValueError
        The image cannot be read; the message says why and what pose to hold instead.
    """
    grey = check_grey(grey)
    if grey.dtype != np.uint8:
        grey = np.clip(np.rint(grey * 255), 0, 255).astype(np.uint8)
    grey = flat_field(grey, rig.camera)      # the lens's fall-off undone: the same contrast in the corners
    if isinstance(target, CharucoBoard):
        from psvs.targets.charuco import detect_charuco
        return detect_charuco(grey, target, rig)
    return _detect_circles(grey, target, rig, depths_mm)


def disc_size_px(target, rig: Rig, depths_mm) -> tuple[float, float]:
    """The discs' diameters (px) at the far and near ends of ``depths_mm`` (each view: a pinhole at its
    virtual centre)."""
    c = rig.camera
    f_px = c.focal_length_mm / min(c.pixel_pitch_mm)
    near, far = (z - rig.virtual_z_mm for z in depths_mm)
    return target.diameter_mm * f_px / far, target.diameter_mm * f_px / near


#: How far a build's disparity may be from the nominal design's, as a factor either way (the mv1440
#: build's is up to 40 % off at 1.2 m).
DISPARITY_SLACK = 2.0


def disparity_per_size(rig: Rig, diameter_mm: float) -> np.ndarray:
    """The disparity a disc of ``diameter_mm`` has per px of its image's widest diameter, (least, most): each
    view a pinhole at its virtual centre, both scale as 1 / (z - z_v), so their ratio is about the baseline
    over the diameter at any depth; widened by :data:`DISPARITY_SLACK` either way for a build."""
    ratio = rig.mirrors.baseline_mm / diameter_mm
    return np.array([ratio / DISPARITY_SLACK, ratio * DISPARITY_SLACK])


def _lattice_of(target) -> tuple[np.ndarray, np.ndarray, float]:
    """The target's lattice (N, 2) int units, a label step -> units map, the nearest neighbours' mm."""
    if isinstance(target, AsymmetricCircleGrid):
        return target.lattice(), np.array([[1, -1], [1, 1]]), target.spacing_mm * math.sqrt(2)
    j, i = np.meshgrid(np.arange(target.cols), np.arange(target.rows))
    return np.column_stack([j.ravel(), i.ravel()]), np.eye(2, dtype=int), target.spacing_mm


def _detect_circles(grey: np.ndarray, target, rig: Rig, depths_mm) -> TargetDetection:
    """A circle grid (symmetric or asymmetric) in both views: discs, twins, labels, trust (module docstring)."""
    n_target = len(target.centres_mm())
    far_px, near_px = disc_size_px(target, rig, depths_mm)
    discs = find_discs(grey, (max(MIN_DISC_PX, 0.5 * far_px), 1.25 * near_px))
    if len(discs) < 4:
        raise ValueError(f"found {len(discs)} disc(s), expected {2 * n_target} ({n_target} per view): "
                         + _advice_none(grey, far_px))
    pts = np.array([d.centre_px for d in discs])
    radius = np.array([d.radius_px for d in discs])
    lattice, to_units, nn_mm = _lattice_of(target)
    reach = REACH_OVER_STEP * radius * nn_mm / (target.diameter_mm / 2)
    merged = radius > MERGED_SIZE * np.median(radius)           # two discs in one blob: one of each view
    widest = np.array([2 * max(d.ellipse.axes_px) for d in discs])
    pairs = pair_twins(pts, reach, rig, sizes_px=radius, prefer=lambda p: _size_misfit(pts, p, rig, nn_mm),
                       shared=merged, weights=[len(d.ellipse.rim_px) / RIM_RAYS for d in discs],
                       shift_px=disparity_per_size(rig, target.diameter_mm) * widest[:, None])
    if len(pairs) < 4:
        raise ValueError(f"found {len(discs)} disc(s) but only {len(pairs)} twin pair(s) along the rig's epipolar "
                         "curves: hold the whole card in both views (nearer the middle of the image)")
    size = 2 * float(np.median(radius[pairs]))
    if size < MIN_DISC_PX:
        raise ValueError(f"the card's discs are {size:.1f} px across, below the {MIN_DISC_PX:g} px that are located "
                         "to a tenth of a pixel: hold the card closer")
    labels = label_lattice(pts[pairs[:, 0]])
    ok = labels[:, 0] != -9999
    pairs, labels = pairs[ok], labels[ok]
    ids, certain = None, False
    if len(pairs) >= 4:
        # image directions of the label axes: an affine fit of the labelled left-view points
        A = np.column_stack([labels, np.ones(len(labels))])
        coef, *_ = np.linalg.lstsq(A, pts[pairs[:, 0]], rcond=None)
        ids, certain = place_on_target(labels, lattice, to_units, coef[:2])
    if ids is None:
        raise ValueError(f"{len(pairs)} paired disc(s) do not form the {_name(target)}: "
                         + _advice_partial(pts[pairs[:, 0]] if len(pairs) else pts, grey, radius))
    even = np.array([d.ellipse.background_spread <= MAX_BACKGROUND_SPREAD
                     and len(d.ellipse.rim_px) >= MIN_RIM_SHARE * RIM_RAYS for d in discs])
    even &= ~merged
    shifts = pts[pairs[:, 0]] - pts[pairs[:, 1]]
    keep = _consistent_shifts(labels, shifts, coef[:2]) \
        & _on_one_plane(labels, pts[pairs], rig, nn_mm, even[pairs[:, 0]] & even[pairs[:, 1]])
    pairs, ids = pairs[keep], ids[keep]
    reliable = even[pairs[:, 0]] & even[pairs[:, 1]] & _like_neighbours(labels[keep], radius[pairs])
    order = np.argsort(ids)
    return TargetDetection(ids[order], pts[pairs[order, 0]], pts[pairs[order, 1]], reliable[order],
                           len(ids) == n_target, certain)


def _size_misfit(pts: np.ndarray, pairs: np.ndarray, rig: Rig, nn_mm: float) -> float:
    """How far (mm) the pairs' points, triangulated through the nominal rig, are from the target's nearest
    neighbour distance (median over points): a pairing one column off puts the card at another depth and
    another size. The nominal rig's depth may be off by far more on a build, so this only breaks ties."""
    from scipy.spatial import cKDTree

    from psvs.measure.triangulate import triangulate
    xyz = triangulate(pts[pairs[:, 0]], pts[pairs[:, 1]], rig, model="exact").points_mm
    xyz = xyz[np.isfinite(xyz).all(axis=1)]
    if len(xyz) < 2:
        return np.inf
    d, _ = cKDTree(xyz).query(xyz, k=2)
    return float(abs(np.median(d[:, 1]) - nn_mm))


#: A blob this much larger than the median disc is taken for two discs merged (a card tilted 25 deg at
#: 400 mm changes its discs' size by 6 % across).
MERGED_SIZE = 1.2
#: A disc more than this much larger or smaller than its lattice neighbours (same view) is two discs
#: merged into one blob (a union too round to split) or part of one: not trusted.
MAX_SIZE_CHANGE = 0.12


def _like_neighbours(labels: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Pairs (n,) whose discs' radii (n, 2: left, right view) are within :data:`MAX_SIZE_CHANGE` of the
    median of their lattice neighbours' in the same view (a tilted card changes it far less per step)."""
    ok = np.ones(len(labels), bool)
    for k, lab in enumerate(labels):
        near = np.abs(labels - lab).max(axis=1) == 1
        if near.sum() >= 2:
            ref = np.median(radii[near], axis=0)
            ok[k] = bool((np.abs(radii[k] / ref - 1) <= MAX_SIZE_CHANGE).all())
    return ok


def _consistent_shifts(labels: np.ndarray, shifts_px: np.ndarray, axes_px: np.ndarray) -> np.ndarray:
    """Pairs whose twin shift (left - right, px) agrees with their lattice neighbours' (median of those
    within one step) to a quarter of the shorter step: a twin taken from the wrong disc is a step off."""
    step = float(min(np.linalg.norm(axes_px, axis=1)))
    keep = np.ones(len(labels), bool)
    for k, lab in enumerate(labels):
        near = np.abs(labels - lab).max(axis=1) == 1
        if near.sum() >= 2:
            keep[k] = np.linalg.norm(shifts_px[k] - np.median(shifts_px[near], axis=0)) <= 0.25 * step
    return keep


#: A pair triangulated farther than this share of the target's step from the plane lattice its neighbours
#: fit took a disc of the other view for its twin (where the two views' columns meet).
LATTICE_TOL = 0.25


def _on_one_plane(labels: np.ndarray, pairs_px: np.ndarray, rig: Rig, nn_mm: float,
                  even: np.ndarray) -> np.ndarray:
    """Pairs (n, 2, 2: left and right px) to keep: those of discs read on an even ground (``even`` (n,)
    bool) whose triangulated point lies within :data:`LATTICE_TOL` steps of the card's lattice, and every
    other (kept for its label, not trusted: a merged disc's centre is biased anyway). A plane lattice is
    affine in its labels (3-D = origin + i a + j b), so an affine fit of the labels to the even pairs'
    points triangulated through the nominal rig (whose errors on a build bend it smoothly, by far less than
    a step) explains every true twin; the fit is trimmed (points beyond three median deviations left out,
    five rounds). A wrong twin a quarter step off in the image puts its point a tenth of the depth off
    the card, which a neighbours' shift median (:func:`_consistent_shifts`) lets pass where the two views'
    columns meet."""
    from psvs.measure.triangulate import triangulate
    xyz = triangulate(pairs_px[:, 0], pairs_px[:, 1], rig, model="exact").points_mm
    ok = np.isfinite(xyz).all(axis=1)
    fit = ok & even
    if fit.sum() < 6:
        return np.ones(len(labels), bool)
    xyz = np.where(ok[:, None], xyz, 0.0)
    T = np.column_stack([labels, np.ones(len(labels))]).astype(np.float64)
    for _ in range(5):
        A, *_ = np.linalg.lstsq(T[fit], xyz[fit], rcond=None)
        r = np.where(ok, np.linalg.norm(xyz - T @ A, axis=1), np.inf)
        fit = ok & even & (r <= max(3 * 1.4826 * float(np.median(r[fit])), 0.02 * nn_mm))
        if fit.sum() < 6:
            return np.ones(len(labels), bool)
    return ~even | (r <= LATTICE_TOL * nn_mm)


def _name(target) -> str:
    if isinstance(target, AsymmetricCircleGrid):
        return f"{target.rows}x{target.cols} asymmetric circle grid"
    return f"{target.rows}x{target.cols} circle grid"


def _advice_none(grey: np.ndarray, far_px: float) -> str:
    lo, hi = float(grey.min()), float(grey.max())
    if hi == lo:
        return "the image is blank (no contrast)"
    if hi - lo < MIN_CONTRAST:
        return f"the image's contrast is too low: grey levels {lo:g}..{hi:g} of 255 (light the card, expose longer)"
    return ("no target in view: hold the whole card in both views, within the working range "
            f"(its discs at least {MIN_DISC_PX:g} px across; {far_px:.1f} px at the farthest)")


def _advice_partial(pts: np.ndarray, grey: np.ndarray, radius: np.ndarray) -> str:
    """What to change: a card at the image's border is partly out of view; discs near the detector's
    smallest are too far; otherwise the views are too entangled (turn the card)."""
    h, w = grey.shape
    r = float(np.median(radius))
    if (pts[:, 0] < 3 * r).any() or (pts[:, 0] > w - 1 - 3 * r).any() or (pts[:, 1] < 3 * r).any() \
            or (pts[:, 1] > h - 1 - 3 * r).any():
        return "the card is partly out of view: move it toward the middle of the image"
    if 2 * r < 2 * MIN_DISC_PX:
        return f"its discs are {2 * r:.1f} px across, too small to separate: hold the card closer"
    return ("the two views' discs lie on top of each other: turn the card (about the vertical) or hold it "
            "farther, so that the two copies of the card overlap less")
