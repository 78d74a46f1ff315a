"""Track one matched edge through a frame sequence: the paper's seeded algorithm (III.3) on every frame,
re-seeded at the edge's new position.

Frame 1 is seeded by the user (the paper's double-click, snapped to the nearest edge pixel). On each later
frame the seed is predicted from its last motion (constant velocity), snapped to the nearest edge pixel of
the new edge map, and accepted when the seeded match finds a twin whose disparity continues the last one;
otherwise the next-nearest candidates are tried. The search radius and the allowed disparity change grow
with every frame the edge stays lost. The seed then moves to the matched left edge's pixel nearest the prediction, so it
follows the edge as the object moves and changes size.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from psvs._validate import check_count, check_grey, check_positive
from psvs.imaging.edge_noise import EdgeStability, edge_stability
from psvs.imaging.pipeline import PAPER, Pipeline
from psvs.match.auto import image_chance, twin_lags
from psvs.match.chance import agreeing_rows, seed_pair_stands
from psvs.match.correspondence import MatchParams, automatic_match, finish_pairs, seed_rows, unshown_rows_reason
from psvs.match.edges import edge_pixels
from psvs.match.pairs import EdgePair
from psvs.match.seeded import match_seeded
from psvs.optics.illumination import flat_field
from psvs.optics.rig import Rig
from psvs.optics.scale import pixel_scale
from psvs.optics.search_range import disparity_range, rectification_for

#: A tracked edge's pixel count may grow this many times from one frame to the next before its edges are asked
#: whether they are the scene's or the sensor's noise (:meth:`EdgeTracker._speckled`); the first frame's always are.
SPECKLE_GROWTH = 1.5
#: Rows either side of the tracked pair's rows read for that test, and the fewest rows it reads.
SPECKLE_MARGIN_PX = 8
SPECKLE_MIN_ROWS = 2 * SPECKLE_MARGIN_PX + 1


@dataclass(frozen=True, eq=False)
class TrackStep:
    """One frame's result: frame index (from 0), the seed used (u, v) px (None when lost), the matched pair
    (sub-pixel, with points_mm) or None, median disparity (px) and median depth Z (mm; NaN when lost),
    processing time (s) and a short status message."""

    frame: int
    seed_px: tuple[int, int] | None
    pair: EdgePair | None
    disparity_px: float
    depth_mm: float
    elapsed_s: float
    message: str

    @property
    def ok(self) -> bool:
        return self.pair is not None


def nearest_edge_pixels(edges: np.ndarray, point_px, radius_px: float, k: int = 1) -> np.ndarray:
    """Up to ``k`` edge pixels (k, 2) int (u, v) of the (H, W) bool map nearest to ``point_px`` (u, v),
    within ``radius_px``, nearest first (an empty (0, 2) array when there is none)."""
    h, w = edges.shape
    u0, v0 = float(point_px[0]), float(point_px[1])
    r = int(np.ceil(radius_px))
    a, b = max(0, int(round(v0)) - r), min(h, int(round(v0)) + r + 1)
    c, d = max(0, int(round(u0)) - r), min(w, int(round(u0)) + r + 1)
    if a >= b or c >= d:
        return np.zeros((0, 2), int)
    vv, uu = np.nonzero(edges[a:b, c:d])
    uu, vv = uu + c, vv + a
    dist = np.hypot(uu - u0, vv - v0)
    keep = dist <= radius_px
    order = np.argsort(dist[keep], kind="stable")[:k]
    return np.column_stack([uu[keep][order], vv[keep][order]])


@dataclass(frozen=True)
class TrackerParams:
    """Tuning of :class:`EdgeTracker`.

    Parameters
    ----------
    snap_px : float
        How far from the user's seed the first edge pixel may be, px.
    search_px : float
        How far from the predicted seed an edge pixel is looked for on later frames, px; after k lost
        frames, (k + 1) times that.
    max_jump_px : float
        Largest change of the edge's median disparity between two frames, px; after k lost frames,
        (k + 1) times that.
    min_pairs : int
        Fewest matched pixel pairs for a frame to count as tracked.
    candidates : int
        Edge pixels tried, nearest the predicted seed first.

    The three lengths are in px of the paper's camera (1130 px per unit tan(angle)): :class:`EdgeTracker`
    scales them to its rig's camera (:func:`psvs.optics.scale.pixel_scale`, :meth:`scaled`), so an edge
    moving so many mm is followed alike on a 640x480 and a 1440x1080 camera.
    """

    snap_px: float = 6.0
    search_px: float = 25.0
    max_jump_px: float = 12.0
    min_pairs: int = 10
    candidates: int = 4

    def __post_init__(self):
        for name in ("snap_px", "search_px", "max_jump_px"):
            check_positive(getattr(self, name), name, "px")
        for name in ("min_pairs", "candidates"):
            check_count(getattr(self, name), name)

    def scaled(self, factor: float) -> "TrackerParams":
        """The same tuning with its lengths (snap, search, jump) times ``factor`` (a camera's pixel scale)."""
        return replace(self, snap_px=self.snap_px * factor, search_px=self.search_px * factor,
                       max_jump_px=self.max_jump_px * factor)


class EdgeTracker:
    """Follow the left-view edge under ``seed_px`` frame to frame and report its depth.

    Parameters
    ----------
    rig : Rig
    seed_px : (u, v)
        A point on (or within ``params.snap_px``, scaled to the camera, of) a left-view edge in the first
        frame, px.
    pipeline : Pipeline
        The image pipeline (default: the paper's median 3x3, threshold 92, Roberts).
    near_mm, far_mm : float
        Working depth range (sets the disparities searched).
    match : MatchParams
        Sub-pixel refinement and the triangulation model of each frame's pair.
    params : TrackerParams
    frame_check : callable, optional
        ``frame_check(grey)``: the frame's self-check (a :class:`psvs.health.check.HealthCheck`, e.g. of
        :func:`psvs.health.check.check_frames` over near..far), asked of a first frame none of whose pairs
        decisively fits the rig's rows (:meth:`_rows_unshown`); ``psvs live`` and the page pass it. Without it
        such a frame is taken on its pairs alone.
    """

    def __init__(self, rig: Rig, seed_px, *, pipeline: Pipeline = PAPER, near_mm: float = 400.0,
                 far_mm: float = 1200.0, match: MatchParams = MatchParams(), params: TrackerParams = TrackerParams(),
                 frame_check=None):
        try:
            seed = np.array([float(c) for c in seed_px])
        except (TypeError, ValueError):
            seed = np.zeros(0)
        if seed.shape != (2,) or not np.all(np.isfinite(seed)):
            raise ValueError(f"seed must be two numbers (u, v) in px, got {seed_px!r}")
        w, h = rig.camera.image_size_px
        if not (0 <= seed[0] < w and 0 <= seed[1] < h):
            raise ValueError(f"seed ({seed[0]:g}, {seed[1]:g}) is outside the {w}x{h} image")
        self.rig, self.pipeline, self.match = rig, pipeline, match
        self.params = params.scaled(pixel_scale(rig.camera))   # the paper camera's px to this camera's
        self.rect = rectification_for(rig, near_mm, far_mm)       # a build: twins on rectified rows
        self.range_px = twin_lags(disparity_range(rig, near_mm, far_mm, self.rect))
        self.frame_check = frame_check
        self._seed = seed
        self._velocity = np.zeros(2)
        self._disparity = None          # last median disparity (px); None before the first match
        self._lost = 0                  # frames since the edge was last tracked
        self._pixels = 0                # the last tracked pair's pixel count
        self._frame = 0

    def _frame_chance(self, edges: np.ndarray, grey: np.ndarray):
        """(Whether the frame holds twins beyond chance, psvs.match.auto.image_chance; the edge pixels it read,
        :func:`~psvs.match.edges.edge_pixels`, which each frame's rows check reads too), asked on every frame
        (2.5 ms at 640 x 480, 7.4 ms at 1440 x 1080): the paper's algorithm pairs the seed's edge with whatever
        agrees best, on noise or stripes as readily as on a twin. With the twins below the range a pair must not
        contradict (psvs.match.chance.Elsewhere): an edge that leaves the range beyond its far limit pairs, a
        few frames on, with another edge inside it (an adversarial trial: Fig. 5b moving 1100 -> 1500 mm was
        tracked at 750 mm for 1520)."""
        px = edge_pixels(edges, self.rect)
        return image_chance(edges, self.range_px, params=self.match.auto, grey=grey, rect=self.rect, px=px,
                            elsewhere=True), px

    def _speckled(self, grey: np.ndarray, pair: EdgePair, first: bool) -> EdgeStability | None:
        """On the first frame, and when the edge's pixels grew :data:`SPECKLE_GROWTH` times or more since the
        last tracked frame (both counted as the seeded match gives them), whether the pipeline's edges on the
        pair's rows of the complex image (:data:`SPECKLE_MARGIN_PX` either side, at least
        :data:`SPECKLE_MIN_ROWS`, the whole width) are mostly the sensor's noise
        (:func:`psvs.imaging.edge_noise.edge_stability`, as ``match`` asks of the whole frame): the stability,
        or None when they are the scene's or were not asked. An object whose grey sits at the pipeline's
        threshold turns its area to speckle, which pairs at many lags (an adversarial trial: a disc at grey 92
        under the paper's threshold of 92 tracked at 743.7 mm for 740 on 640 pairs, three times the frames
        before, exit 0; ``match`` refused the frame as noise)."""
        if not first and len(pair.disparity_px) < SPECKLE_GROWTH * self._pixels:
            return None
        left, right = pair.left_px, pair.right_px
        if self.rect is not None:            # a build's pairs are on its rectified grids: their image rows
            left, right = self.rect.to_complex(left, "left"), self.rect.to_complex(right, "right")
        rows = np.concatenate([left[:, 1], right[:, 1]])
        rows = rows[np.isfinite(rows)]
        h = grey.shape[0]
        if not rows.size or h < SPECKLE_MIN_ROWS:
            return None
        r0 = max(int(np.floor(rows.min())) - SPECKLE_MARGIN_PX, 0)
        r1 = min(int(np.ceil(rows.max())) + SPECKLE_MARGIN_PX + 1, h)
        if r1 - r0 < SPECKLE_MIN_ROWS:       # a short edge at the image's border: the rows about it
            r0 = min(max((r0 + r1 - SPECKLE_MIN_ROWS) // 2, 0), h - SPECKLE_MIN_ROWS)
            r1 = r0 + SPECKLE_MIN_ROWS
        stability = edge_stability(grey[r0:r1], self.pipeline)
        return stability if stability.noise else None

    def _rows_unshown(self, grey: np.ndarray) -> str:
        """Why the first frame (H, W) cannot show that the rig's rows hold when no pair of it decisively fits
        them (:func:`psvs.match.correspondence.unshown_rows_reason`: its self-check cannot judge either), or
        why it shows they do not (drifted); "" when its self-check says healthy. As ``match --seed`` refuses
        such a frame (an adversarial trial: a card of the mv1440_misaligned build tracked through the mv1440
        design file at 767 mm for 650, exit 0, where match refused)."""
        if self.frame_check is None:
            return ""
        check = self.frame_check(grey)
        if check.verdict == "drifted":
            return check.misfit_words
        return unshown_rows_reason(1, check)

    def step(self, grey: np.ndarray) -> TrackStep:
        """Process the next frame (H, W) uint8 and return its :class:`TrackStep`."""
        t0 = time.perf_counter()
        grey = check_grey(grey, "frame")
        w, h = self.rig.camera.image_size_px
        if grey.shape != (h, w):
            raise ValueError(f"frame is {grey.shape[1]}x{grey.shape[0]} px but the rig's camera is {w}x{h} px")
        frame, self._frame = self._frame, self._frame + 1
        raw, grey = grey, flat_field(grey, self.rig.camera)    # the lens's fall-off undone (psvs.optics.illumination)
        edges = self.pipeline.run(grey)
        first = self._disparity is None
        predicted = self._seed + self._velocity
        p = self.params
        radius = p.snap_px if first else p.search_px * (1 + self._lost) + float(np.hypot(*self._velocity))
        cands = nearest_edge_pixels(edges, predicted, radius, p.candidates)
        msg = "no edge pixel near the seed" if first else "edge lost"
        chance = automatic = px = unshown = None
        for cand in cands:
            pair = match_seeded(edges, cand, self.range_px, n_seeds=self.match.n_seeds, rect=self.rect)
            if len(pair) < p.min_pairs:
                continue
            # asked once a frame, when a candidate first pairs: a frame turned to noise (a covered lens, a
            # lamp's flash) loses the edge there, not several frames later at whatever depth noise pairs at
            chance, px = self._frame_chance(edges, grey) if chance is None else (chance, px)
            if not chance.answered:
                msg = f"no twin beyond chance in the frame: {chance.describe()}"
                break
            speckle = self._speckled(grey, pair, first)
            if speckle is not None:
                msg = (f"the seed's edge is not the scene's: {speckle.describe()}" if first else
                       f"edge lost (its edge map turned to the sensor's noise): {speckle.describe()}")
                continue
            if not first and chance.elsewhere is not None and chance.elsewhere.beats_pixels(
                    pair.left_px, pair.right_px, agreeing_rows(pair, self.match.auto.tol_px), chance.level_rows):
                msg = ("edge lost (its pixels twin more strongly below the range: a scene beyond the far limit, or an "
                       "edge of speckle, which twins at any lag, as an object whose grey is at the threshold gives)")
                continue
            if first:                   # the edge taken as match --seed takes it (the automatic matcher run once)
                automatic = automatic or automatic_match(edges, self.range_px, params=self.match, grey=grey,
                                                         rect=self.rect)
                if not seed_pair_stands(pair, chance, lambda: automatic().pairs, self.match.auto.tol_px):
                    msg = ("the seed's edge has no twin beyond chance: the twin it pairs with agrees on too few "
                           f"rows to stand alone, and no pair of the automatic matcher backs it ({chance.describe()})")
                    continue
            rows = seed_rows(pair, px, self.match)          # as match --seed asks, on every frame
            if rows.refuses:
                msg = (f"the seed's edge has no twin on the rig's rows: {rows.describe()}" if first else
                       f"edge lost (its twin lines up off the rig's rows: knocked?): {rows.describe()}")
                continue
            if first and not (rows.fits or automatic().rows.fits):
                unshown = self._rows_unshown(raw) if unshown is None else unshown
                if unshown:
                    msg = unshown
                    continue
            d = float(np.median(pair.disparity_px))
            if not first and abs(d - self._disparity) > p.max_jump_px * (1 + self._lost):
                msg = f"edge lost (disparity jumped {d - self._disparity:+.1f} px)"
                continue
            seen = len(pair.disparity_px)      # as the seeded match gives them (:meth:`_speckled`'s growth)
            finished = finish_pairs(grey, [pair], self.rig, subpixel=self.match.subpixel, model=self.match.model,
                                    rect=self.rect)
            if not finished:            # no row pins a disparity (the edge runs along the rows), or none is lit
                msg = "the edge runs along the rows: no row pins its disparity"
                continue
            pair, = finished
            z = pair.points_mm[:, 2]
            if not np.any(np.isfinite(z)):
                continue
            new_seed = np.rint(pair.left_px[np.argmin(np.hypot(*(pair.left_px - predicted).T))])
            self._velocity = np.zeros(2) if first else new_seed - self._seed
            self._seed = new_seed
            self._disparity = float(np.median(pair.disparity_px))
            self._pixels = seen
            self._lost = 0
            return TrackStep(frame, (int(new_seed[0]), int(new_seed[1])), pair, self._disparity,
                             float(np.nanmedian(z)), time.perf_counter() - t0, "tracked")
        if not first:
            self._velocity = np.zeros(2)
            self._lost += 1
        return TrackStep(frame, None, None, float("nan"), float("nan"), time.perf_counter() - t0, msg)
