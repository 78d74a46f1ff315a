"""From a complex image to matched, triangulated edges: pipeline -> match (seeded or automatic) ->
sub-pixel refinement -> triangulation (issue 2's models, refraction-corrected by default)."""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.imaging.pipeline import PAPER, Pipeline
from psvs.match.auto import Unmatched, match_auto
from psvs.match.pairs import EdgePair
from psvs.match.seeded import match_seeded
from psvs.match.subpixel import refine_pairs
from psvs.measure.triangulate import triangulate, twin_rows
from psvs.optics.design import working_range
from psvs.optics.rig import Rig

#: Extra disparity margin (px) around the working range's ideal disparities (plate shift, edge width).
RANGE_MARGIN_PX = 4.0


@dataclass(frozen=True, eq=False)
class MatchResult:
    """pairs (with points_mm), unmatched edges (automatic mode), the edge map (H, W) bool, the disparity
    range used (px) and the pipeline's stages [(op, image)]."""

    pairs: list[EdgePair]
    unmatched: list[Unmatched]
    edges: np.ndarray
    disparity_range_px: tuple[float, float]
    stages: list


def disparity_range(rig: Rig, near_mm: float, far_mm: float) -> tuple[float, float]:
    """Disparities (px) of the working range near..far, widened by :data:`RANGE_MARGIN_PX`."""
    wr = working_range(rig, near_mm, far_mm)
    return (max(1.0, wr.disparity_px[0] - RANGE_MARGIN_PX), wr.disparity_px[1] + RANGE_MARGIN_PX)


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
                far_mm: float = 1200.0, subpixel: bool = True, model: str = "refraction", n_seeds: int = 10,
                min_rows: int = 10) -> MatchResult:
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
    subpixel : bool
        Refine every matched pixel to sub-pixel on the grey image.
    model : {'paper', 'refraction', 'exact'}
        Triangulation model (issue 2).

    Returns
    -------
    MatchResult
    """
    grey = np.asarray(grey)
    if grey.ndim != 2 or grey.dtype != np.uint8:
        raise ValueError(f"image must be a grey (H, W) uint8 image, got shape {grey.shape} {grey.dtype}")
    w, h = rig.camera.image_size_px
    if grey.shape != (h, w):
        raise ValueError(f"image is {grey.shape[1]}x{grey.shape[0]} px but the rig's camera is {w}x{h} px")
    lo, hi, _, _ = cv2.minMaxLoc(grey)
    if lo == hi:
        raise ValueError("image is blank (one grey level): nothing to match")
    rng = disparity_range(rig, near_mm, far_mm)
    edges, stages = pipeline.run(grey, keep=True)
    if seed_px is not None:
        pair = match_seeded(edges, seed_px, rng, n_seeds=n_seeds)
        pairs, unmatched = ([pair] if len(pair) else []), []
    else:
        auto = match_auto(edges, rng, min_rows=min_rows, grey=grey)
        pairs, unmatched = auto.pairs, auto.unmatched
    return MatchResult(finish_pairs(grey, pairs, rig, subpixel=subpixel, model=model), unmatched, edges, rng, stages)


def finish_pairs(grey: np.ndarray, pairs: list[EdgePair], rig: Rig, *, subpixel: bool = True,
                 model: str = "refraction") -> list[EdgePair]:
    """Refine integer pixel pairs to sub-pixel on the grey (H, W) uint8 image, correct their rows for the
    plate (:func:`correct_rows`) and triangulate them (points_mm, frame C, mm)."""
    out = []
    for pair in pairs:
        if subpixel:
            pair = correct_rows(grey, refine_pairs(grey, pair), rig)
        res = triangulate(pair.left_px, pair.right_px, rig, model=model)
        out.append(pair.with_points(res.points_mm))
    return out
