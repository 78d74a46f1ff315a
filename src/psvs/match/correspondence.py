"""From a complex image to matched, triangulated edges: pipeline -> match (seeded or automatic) ->
sub-pixel refinement -> triangulation (psvs.measure.triangulate's models, refraction-corrected by default).

On a build (misaligned mirrors or a distorting lens, :func:`psvs.optics.rectify.needs_rectification`) the
two views of a point no longer share a row of the complex image: matching then pairs edge pixels on the
rows of the dual rectification (psvs.optics.rectify), refines them on the two rectified images, maps them
back to the complex image and triangulates them with the exact model of the build."""
from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from psvs._validate import check_grey
from psvs.imaging.edge_noise import EdgeStability, edge_stability
from psvs.imaging.pipeline import PAPER, Pipeline
from psvs.match.auto import AutoParams, Unmatched, image_chance, match_auto, twin_lags
from psvs.match.chance import Chance, seed_pair_stands
from psvs.match.edges import edge_pixels
from psvs.match.pairs import EdgePair
from psvs.match.rows import RowCheck, check_pair
from psvs.match.seeded import match_seeded
from psvs.match.subpixel import refine_pairs
from psvs.measure.triangulate import MODELS, default_model, triangulate, twin_rows
from psvs.optics.illumination import flat_field
from psvs.optics.rectify import Rectification
from psvs.optics.rig import Rig
from psvs.optics.search_range import disparity_range, rectification_for
from psvs.optics.trace import lit_pairs


@dataclass(frozen=True)
class MatchParams:
    """How :func:`match_image` matches and finishes the pairs.

    Parameters
    ----------
    subpixel : bool
        Refine every matched pixel to sub-pixel on the grey image.
    model : {'paper', 'refraction', 'exact'}, optional
        Triangulation model; default :func:`default_model` (exact on a build).
    n_seeds : int
        The seeded algorithm's seeds on the corresponding edge (2-100, the paper's range).
    auto : AutoParams
        The automatic mode's tuning (:func:`psvs.match.auto.match_auto`).
    """

    subpixel: bool = True
    model: str | None = None
    n_seeds: int = 10
    auto: AutoParams = AutoParams()

    def __post_init__(self):
        if not isinstance(self.subpixel, (bool, np.bool_)):
            raise ValueError(f"subpixel must be True or False, got {self.subpixel!r}")
        if self.model is not None and self.model not in MODELS:
            raise ValueError(f"model must be one of {', '.join(MODELS)} or None, got {self.model!r}")
        if isinstance(self.n_seeds, bool) or not isinstance(self.n_seeds, (int, np.integer)) \
                or not 2 <= self.n_seeds <= 100:
            raise ValueError(f"n_seeds must be an integer in 2..100 (the paper's range), got {self.n_seeds!r}")
        if not isinstance(self.auto, AutoParams):
            raise ValueError(f"auto must be an AutoParams, got {type(self.auto).__name__}")


@dataclass(frozen=True, eq=False)
class MatchResult:
    """pairs (with points_mm), unmatched edges (automatic mode), the edge map (H, W) bool, the disparity
    range used (px), the pipeline's stages [(op, image)] and how the twins stood against chance
    (:class:`psvs.match.chance.Chance`: whether the image holds twins at all, asked in either mode; no pair
    when it is not ``answered``), and what the pairs said of the rig's rows
    (:class:`psvs.match.rows.RowCheck`, of the seed's pair from a seed; no pair when it ``refuses``; None
    when there was no pair to check). ``rows_fit``: how many of the image's edge pairs decisively stand on the
    rig's rows (:mod:`psvs.match.rows`): the automatic matcher's; from a seed, its pair's, else the
    automatic matcher's on the same image. 0 when no pair shows the rows hold (steep straight edges fit
    every row: :func:`rows_unshown`). ``edge_noise``: how the pipeline's edges stood a fresh draw of the
    frame's noise (:func:`psvs.imaging.edge_noise.edge_stability`); no pair when they are mostly noise."""

    pairs: list[EdgePair]
    unmatched: list[Unmatched]
    edges: np.ndarray
    disparity_range_px: tuple[float, float]
    stages: list
    chance: Chance
    rows: RowCheck | None = None
    rows_fit: int = 0
    edge_noise: EdgeStability | None = None


def correct_rows(grey: np.ndarray, pair: EdgePair, rig: Rig) -> EdgePair:
    """Move each right-view point to the row where its twin really is.

    The M1 plate shifts the left view's rows slightly (by up to ~0.5 px, depending on position and
    depth), so a point's twin lies on row v_r = v_l + dv, not on the same row. Each pair is triangulated
    exactly and its point projected into the right view to get v_r; the right point then slides along its
    edge to that row, u_r += (du/dv) dv, with the edge direction du/dv = -g_v / g_u from the grey image's
    gradient. Where the edge runs nearly along the row (|g_u| < |g_v| / 2), only v changes.
    """
    if len(pair) == 0:
        return pair
    v_r, ok = twin_rows(pair.left_px, pair.right_px, rig)
    img = np.asarray(grey, dtype=np.float64)
    h, w = img.shape
    u = np.clip(np.rint(pair.right_px[:, 0]).astype(int), 1, w - 2)
    v = np.clip(np.rint(pair.right_px[:, 1]).astype(int), 1, h - 2)
    gu = img[v, u + 1] - img[v, u - 1]
    gv = img[v + 1, u] - img[v - 1, u]
    steep = np.abs(gu) >= 0.5 * np.abs(gv)
    dv = np.where(ok, v_r - pair.right_px[:, 1], 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        du = np.where(ok & steep & (gu != 0), -gv / gu * dv, 0.0)
    right = pair.right_px.copy()
    right[:, 0] += du
    right[:, 1] += dv
    left = pair.left_px
    return EdgePair(left, right, left[:, 0] - right[:, 0], pair.left_label, pair.right_label,
                    pair.shape_disparity_px, pair.points_mm)


def match_image(grey: np.ndarray, rig: Rig, *, seed_px=None, pipeline: Pipeline = PAPER, near_mm: float = 400.0,
                far_mm: float = 1200.0, rect: Rectification | None = None,
                params: MatchParams = MatchParams()) -> MatchResult:
    """Match edges of a complex image and triangulate them.

    Parameters
    ----------
    grey : ndarray, shape (H, W), uint8
        The complex image.
    rig : Rig
        Its size must be the image's.
    seed_px : (u, v) or None
        A pixel on a left-view edge: the paper's algorithm from that seed. None: automatic mode.
    pipeline : Pipeline
        Filters, binarisation and edge detector (default: the paper's median 3x3, threshold 92, Roberts).
    near_mm, far_mm : float
        Working depth range: sets the disparities searched.
    rect : Rectification, optional
        The build's dual rectification to use (default: the rig's over near..far, cached; a caller whose
        working range changes every frame passes one fitted over its whole range).
    params : MatchParams
        Sub-pixel refinement, triangulation model, and each mode's tuning (``n_seeds`` seeded, ``auto``
        automatic).

    Returns
    -------
    MatchResult
        Pairs in complex-image pixels; on a build their disparity is the rectified one. None when the
        pipeline's edges are mostly the frame's noise (``edge_noise``).
    """
    grey = check_grey(grey)
    w, h = rig.camera.image_size_px
    if grey.shape != (h, w):
        raise ValueError(f"image is {grey.shape[1]}x{grey.shape[0]} px but the rig's camera is {w}x{h} px")
    lo, hi, _, _ = cv2.minMaxLoc(grey)
    if lo == hi:
        raise ValueError("image is blank (one grey level): nothing to match")
    grey = flat_field(grey, rig.camera)     # the lens's fall-off undone: the pipeline's levels hold everywhere
    if rect is None:
        rect = rectification_for(rig, near_mm, far_mm)
    rng = twin_lags(disparity_range(rig, near_mm, far_mm, rect))
    edges, stages = pipeline.run(grey, keep=True)
    if seed_px is not None:
        pair = match_seeded(edges, seed_px, rng, n_seeds=params.n_seeds, rect=rect)
        px = edge_pixels(edges, rect)            # labelled once: the chance test and the rows' check read them
        chance = image_chance(edges, rng, params=params.auto, grey=grey, rect=rect, px=px, elsewhere=True)
        rows = seed_rows(pair, px, params) if len(pair) and chance.answered else None
        automatic = automatic_match(edges, rng, params=params, grey=grey, rect=rect)
        stands = rows is not None and not rows.refuses and seed_pair_stands(
            pair, chance, lambda: automatic().pairs, params.auto.tol_px)
        pairs, unmatched = ([pair] if stands else []), []
        fit = (rows.fits or automatic().rows.fits) if stands else 0
    else:
        auto = match_auto(edges, rng, params=params.auto, grey=grey, rect=rect)
        pairs, unmatched, chance, rows, fit = auto.pairs, auto.unmatched, auto.chance, auto.rows, auto.rows.fits
    noise = edge_stability(grey, pipeline)
    if noise.noise:                 # the pairs of noise edges are no answer (docstring of psvs.imaging.edge_noise)
        pairs = []
    finished = finish_pairs(grey, pairs, rig, subpixel=params.subpixel, model=params.model, rect=rect)
    return MatchResult(finished, unmatched, edges, rng, stages, chance, rows, fit, noise)


def rows_unshown(res: MatchResult, check) -> str:
    """Why ``res``'s pairs cannot be shown to stand on the rig's rows, or "": when the image's self-check
    (``check``, :class:`psvs.health.check.HealthCheck` of the same image) cannot judge and no pair decisively
    fits the rows (``res.rows_fit`` 0: steep straight edges fit every row), nothing in the image tells the
    rig's rows from others, and pairs found on them may be wrong ones. A frame flipped upside down through a
    build (a camera's vertical flip) paired Fig. 5b's edges with others at 767-955 mm, its ashtrays standing
    at 690 and 720 mm (an adversarial trial; the frame as taken shows 2 of its 5 pairs on the rows)."""
    if not res.pairs or res.rows_fit > 0:
        return ""
    return unshown_rows_reason(len(res.pairs), check)


def unshown_rows_reason(n_pairs: int, check) -> str:
    """:func:`rows_unshown`'s words for ``n_pairs`` edge pairs none of which decisively fits the rig's rows,
    when the image's self-check (``check``) cannot judge; "" when it can (or there is none)."""
    if check is None or check.verdict != "cannot judge":
        return ""
    pairs = "its edge pair does not" if n_pairs == 1 else f"none of its {n_pairs} edge pairs"
    return (f"nothing in the image shows that the rig's rows hold: its self-check cannot judge ({check.reason}), "
            f"and {pairs} line up on the rig's rows more decisively than some rows off (steep straight edges "
            "fit any row): a frame flipped, or another build's, would give such pairs too. Match a frame with "
            "curved or slanted edges or some texture (psvs check)")


def seed_rows(pair: EdgePair, px, params: MatchParams = MatchParams()) -> RowCheck:
    """Whether a pair found from a seed stands on the rig's rows (:func:`psvs.match.rows.check_pair`: its whole
    edges against every edge pixel, shifted -6..6 rows); ``px`` the frame's :func:`~psvs.match.edges.edge_pixels`.
    A pair that ``refuses`` lines up rows off: the rig does not fit the image (``match --seed`` and live
    tracking's first frame refuse it alike)."""
    return check_pair(pair.left_px, px, pair.shape_disparity_px, params.auto.min_rows)


def automatic_match(edges: np.ndarray, disparity_range_px: tuple[float, float], *, params: MatchParams = MatchParams(),
                    grey: np.ndarray | None = None, rect: Rectification | None = None) -> Callable:
    """The automatic matcher's result on ``edges`` (:func:`psvs.match.auto.match_auto`: its accepted pairs, and
    how many decisively fit the rig's rows), as a function that runs it on its first call and keeps the
    answer: the backing a seeded pair may need (:func:`psvs.match.chance.seed_pair_stands`) and the image's
    rows (:func:`rows_unshown`), asked at most once per image however many seeds are tried."""
    return functools.cache(lambda: match_auto(edges, disparity_range_px, params=params.auto, grey=grey, rect=rect))


def finish_pairs(grey: np.ndarray, pairs: list[EdgePair], rig: Rig, *, subpixel: bool = True,
                 model: str | None = None, rect: Rectification | None = None) -> list[EdgePair]:
    """Refine integer pixel pairs to sub-pixel on the grey (H, W) uint8 image, correct their rows for the
    plate (:func:`correct_rows`) and triangulate them (points_mm, frame C, mm).

    With ``rect`` (a build) the pairs come in rectified coordinates: each side is refined along its row on
    its own view's rectified image (so both stay on one epipolar row), then mapped back to the complex
    image; rows whose point no view pixel sees are dropped (a pair left with none, too). The result is in
    complex-image pixels, with the rectified disparity."""
    model = default_model(rig) if model is None else model
    if rect is not None and subpixel and pairs:
        # only the part of the rectified grid the pairs use (+-6 px for the refinement's neighbours)
        pts = np.concatenate([np.vstack([p.left_px, p.right_px]) for p in pairs if len(p)] or [np.zeros((1, 2))])
        (c0, r0), (c1, r1) = np.floor(pts.min(axis=0)).astype(int) - 6, np.ceil(pts.max(axis=0)).astype(int) + 7
        c0, r0 = max(0, c0), max(0, r0)
        views = tuple(rect.remap_fast(grey, v, (r0, r1, c0, c1)) for v in ("left", "right"))
        shift = np.array([float(c0), float(r0)])
    out = []
    for pair in pairs:
        if rect is None:
            if subpixel:
                pair = refine_pairs(grey, pair)
                if not len(pair):      # no row of it pins a disparity: no pair
                    continue
                pair = correct_rows(grey, pair, rig)
        else:
            if subpixel:
                band = EdgePair(pair.left_px - shift, pair.right_px - shift, pair.disparity_px, pair.left_label,
                                pair.right_label, pair.shape_disparity_px)
                band = refine_pairs(views[0], band, grey_right=views[1])
                pair = EdgePair(band.left_px + shift, band.right_px + shift, band.disparity_px, pair.left_label,
                                pair.right_label, pair.shape_disparity_px)
            left, right = rect.lookup(pair.left_px, "left"), rect.lookup(pair.right_px, "right")
            ok = np.all(np.isfinite(left), axis=1) & np.all(np.isfinite(right), axis=1)
            if not ok.any():       # no view pixel sees any of its points: no pair
                continue
            pair = EdgePair(left[ok], right[ok], pair.disparity_px[ok], pair.left_label, pair.right_label,
                            pair.shape_disparity_px)
        seen = lit_pairs(pair.left_px, pair.right_px, rig)
        if not seen.any():         # every row in a part of a view the glass blocks: an edge of the glass, no pair
            continue
        if not seen.all():
            pair = EdgePair(pair.left_px[seen], pair.right_px[seen], pair.disparity_px[seen], pair.left_label,
                            pair.right_label, pair.shape_disparity_px)
        res = triangulate(pair.left_px, pair.right_px, rig, model=model)
        out.append(pair.with_points(res.points_mm))
    return out
