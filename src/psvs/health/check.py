"""``psvs check``: is this calibration still the rig's? The twins' row offsets over ordinary frames, a smooth
field fitted to them, and a verdict that says on how much evidence it stands (docs/health.md).

Each frame's tiles (:func:`psvs.health.rows.frame_tiles`) that pass their chance test are pooled. A mirror
that moved turns a view's image a little: its rows move by a smooth field over the image (near affine; a
quadratic in u', v' holds it, its curvature no more than a turned view makes: :func:`curvature_bound_px`), so
the field is fitted to the tiles (robustly, :func:`psvs.health.field.robust_fit`: soft-L1, then least squares
on the tiles within a few robust sigmas of it, each tile judged by the residual it would have were it left
out), and the field is what is judged: its RMS and largest value over the judged tiles, which must spread
over the frame (:data:`MIN_REGIONS`: a quadratic through tiles bunched in one part of it extrapolates
anything). A tile's own offset scatters by a few tenths of a pixel (the other view's
texture in each tile); the field averages that down, and its uncertainty (the fit's standard error, the
tiles' overlap and the fit's degrees of freedom counted) is stated beside it. The RMS is the field's own: the
fit's noise variance is taken off its mean square (a rig on its rows reads near 0, not the noise's RMS).

The verdict: ``healthy`` when the field's RMS plus twice its uncertainty is within the tolerance,
``drifted`` when its RMS minus twice its uncertainty is beyond it (twice: Student's t quantile of the same
confidence when the uncertainty rests on few tiles, 2.5 times at the 12 of a first judgement) and still is
with the :data:`SPARE_TILES` tiles that bear it most left out (wrong twins come a few at a time), and
``cannot judge`` otherwise: too
few tiles passed (:data:`MIN_TILES`: too little texture, or the twins too far off to be found even when
searched :data:`psvs.health.rows.FAR_REACH_DEG` either side, which the check does when too few are found
within the usual reach and it cannot judge), the tiles lie in fewer than :data:`MIN_REGIONS` of the frame's
ninths, the texture repeats along the rows or runs along one direction (psvs.health.rows), the tiles
disagree with any smooth field (:data:`MAX_SCATTER_PX`: a scene that moved between the views' exposures is
not one a frame shows; at least :data:`MIN_CONSISTENT` of the tiles must lie on the field), or the field's
uncertainty straddles the tolerance (more frames decide it).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from psvs._validate import check_grey
from psvs.dense.rig_cache import rectification
from psvs.errors import MeasurementError
from psvs.evidence import ROW_TOLERANCE_PX
from psvs.health.field import bounded_lstsq, curvature_bound_px, field_basis, robust_fit
from psvs.health.rows import FAR_REACH_DEG, FrameTiles, frame_tiles, reach_px
from psvs.optics.rectify import needs_rectification
from psvs.optics.rig import Rig

#: The tolerance a calibration is held to by default: the field's RMS, px.
TOLERANCE_PX = ROW_TOLERANCE_PX
#: At least this many tiles must pass their chance test, and lie on the field in at least MIN_REGIONS of the
#: frame's ninths (a 3 x 3 split of the places a tile can stand): a field over the frame is not pinned by
#: tiles bunched in one part of it (a quadratic through them extrapolates anything).
MIN_TILES = 12
MIN_REGIONS = 6
#: Tiles that scatter about the fitted field by more than this (px, robust sigma) cannot be one field.
MAX_SCATTER_PX = 1.0
#: Each pixel lies in this many tiles of a whole frame (they overlap by half along each axis): a refit's evidence
#: per tile is that much less (psvs.calibrate.refit; a judgement counts its own tiles' overlap:
#: :func:`evidence_factors`).
OVERLAP = 4.0
#: At least this share of the tiles above chance must lie on the one field.
MIN_CONSISTENT = 0.6
#: Share of the textured tiles whose peak lay on the searched rows' edge that says "farther than the reach".
EDGE_SHARE = 0.5


@dataclass(frozen=True)
class HealthCheck:
    """What ``psvs check`` found: ``verdict`` ("healthy", "drifted", "cannot judge"), ``reason`` (one line:
    what it judged on, or what it needs), the fitted field's ``row_offset_rms_px`` and ``row_offset_max_px``
    (largest |offset|) over the judged tiles with its ``uncertainty_px`` (NaN when it cannot judge),
    ``scatter_px`` (tiles about the field, robust sigma), ``judged_px`` (pixels of the tiles judged),
    ``tiles`` (judged) of ``tiles_tried``, ``frames``, ``tolerance_px``; the judged tiles' ``centre_px``
    (n, 2) on the left grid with their ``offset_px`` (n,) (measured, less ``expected_px`` (n,), what the rig itself
    makes there: the plate's row shift on the paper's geometry, :mod:`psvs.health.plate_shift`; None: none),
    ``fitted_px`` (n,) the field there, and ``coefficients`` (6,) of the field in the grid's normalised
    coordinates (:func:`field_basis`)."""

    verdict: str
    reason: str
    row_offset_rms_px: float
    row_offset_max_px: float
    uncertainty_px: float
    scatter_px: float
    judged_px: int
    tiles: int
    tiles_tried: int
    frames: int
    tolerance_px: float
    grid_shape: tuple[int, int]
    centre_px: np.ndarray = field(repr=False)
    offset_px: np.ndarray = field(repr=False)
    fitted_px: np.ndarray = field(repr=False)
    coefficients: np.ndarray = field(repr=False)
    disparity_px: np.ndarray = field(repr=False)
    expected_px: np.ndarray | None = field(default=None, repr=False)

    @property
    def misfit_words(self) -> str:
        """A ``drifted`` check as the reason an answer through its rig is refused, in one place for every
        command and the live tracker."""
        return f"the rig does not fit this image: {self.reason} (psvs check; psvs refit or calibrate again)"

    def as_dict(self) -> dict:
        """The check as JSON-ready values (NaN as None)."""
        num = lambda x: None if not np.isfinite(x) else round(float(x), 4)  # noqa: E731
        return {"verdict": self.verdict, "reason": self.reason, "row_offset_rms_px": num(self.row_offset_rms_px),
                "row_offset_max_px": num(self.row_offset_max_px), "uncertainty_px": num(self.uncertainty_px),
                "scatter_px": num(self.scatter_px), "judged_px": int(self.judged_px), "tiles": self.tiles,
                "tiles_tried": self.tiles_tried, "frames": self.frames, "tolerance_px": self.tolerance_px,
                "grid_shape": list(self.grid_shape),
                "tile_centres_px": [[num(u), num(v)] for u, v in self.centre_px],
                "tile_offsets_px": [num(x) for x in self.offset_px],
                "tile_fitted_px": [num(x) for x in self.fitted_px]}


def judged_pairs_px(check: HealthCheck, rig: Rig, near_mm: float = 400.0,
                    far_mm: float = 1200.0) -> tuple[np.ndarray, np.ndarray]:
    """The judged tiles as twin pairs in the complex image: (left view's pixels (n, 2), right view's (n, 2)),
    each tile's centre on the left grid and where its twin was found on the right grid (its disparity along
    the row, its measured offset across), read back through the rectification the check read through
    (``rig``'s over near..far mm)."""
    left = check.centre_px
    measured = check.offset_px if check.expected_px is None else check.offset_px + check.expected_px
    right = left - np.column_stack([check.disparity_px, -measured])
    rect = rectification(rig, near_mm, far_mm)
    if rect is not None:
        left, right = rect.to_complex(left, "left"), rect.to_complex(right, "right")
    return left, right


def checked_tolerance(tolerance_px: float, rig: Rig) -> float:
    """``tolerance_px`` (the twins' field RMS a verdict is judged against, px) when it is a number > 0 and
    below the farthest offset the check can see on ``rig``'s camera (:data:`~psvs.health.rows.FAR_REACH_DEG`
    as rows): a tolerance beyond it would call any field healthy. ValueError otherwise."""
    reach = reach_px(rig, FAR_REACH_DEG)
    if not (math.isfinite(tolerance_px) and 0 < tolerance_px < reach):
        raise ValueError(f"the tolerance must be a number of px > 0 and below the {reach} px the check can see "
                         f"on this camera (a larger one calls any field healthy), got {tolerance_px!r}")
    return float(tolerance_px)


def frame_checker(rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0):
    """One frame's check over near..far mm (:func:`check_frames` of that frame alone), as a function of the
    frame (H, W): the ``frame_check`` a live tracker asks of a first frame whose pairs cannot show the rig's
    rows (:class:`psvs.live.tracker.EdgeTracker`; ``psvs live`` and the page give it)."""
    return lambda grey: check_frames([grey], rig, near_mm, far_mm)


def check_frames(frames, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0,
                 tolerance_px: float = TOLERANCE_PX) -> HealthCheck:
    """Judge a calibration (``rig``) on ordinary frames (a list of (H, W) grey images of any textured scene
    over the working range near..far mm): the module docstring's field and verdict."""
    checked_tolerance(tolerance_px, rig)
    if len(frames) == 0:
        raise ValueError("no frame to check")
    w, h = rig.camera.image_size_px
    grey = []
    for k, f in enumerate(frames):
        g = check_grey(f, f"frame {k + 1}")
        if g.shape != (h, w):
            raise ValueError(f"frame {k + 1} is {g.shape[1]}x{g.shape[0]} px, the rig's camera {w}x{h}")
        grey.append(g)
    check = judge([frame_tiles(g, rig, near_mm, far_mm) for g in grey], tolerance_px)
    beyond = check.verdict == "drifted" and not np.isfinite(check.uncertainty_px)    # peaks on the reach's edge
    too_few = check.verdict == "cannot judge" and check.tiles < MIN_TILES     # twins perhaps beyond the reach
    if not (beyond or too_few):
        return check     # judged, or refused on tiles it found within the reach: a wider search adds chance
    wider = judge([frame_tiles(g, rig, near_mm, far_mm, FAR_REACH_DEG) for g in grey], tolerance_px)
    if wider.verdict != "cannot judge":
        return wider                                                # twins beyond the usual reach, found
    if beyond:      # what lay past the reach's edge is no twin the wider search finds: a texture, not a knock
        return dataclasses.replace(wider, reason=f"{check.reason.split(':')[0]}, but a search {FAR_REACH_DEG:g} deg "
                                   f"either side finds no field of twins: {wider.reason}")
    return check


#: Tiles a quick look at one frame reads (:func:`refuse_if_drifted`, ``quick``), spread over the field: a tenth
#: of a 1440 x 1080 frame's 304, a sixth of a 640 x 480 frame's 224 (0.1-0.3 s against 0.2-1.6 s for all).
QUICK_TILES = 36
#: Tiles a second look reads when the first cannot judge, on an ideal rig (a textured scene judged 11-15 of the
#: 36; 0.06 s on 640 x 480). Not on a build: there a frame of another camera stands far off the rows its
#: rectification makes, the first look tells, and the second cost 0.3 s of a 1.4-2 s call on 1440 x 1080.
SECOND_LOOK_TILES = 108


def refuse_if_drifted(grey, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0,
                      cause: BaseException | None = None, quick: bool = False) -> HealthCheck:
    """The check of one image (:func:`check_frames` over near..far mm) for an answer measured on it through
    ``rig``: :class:`~psvs.errors.MeasurementError` when it reads ``drifted`` (a mirror knocked since the
    calibration, another build's frame: "the rig does not fit this image", its field in figures), else the
    check (``healthy``, or ``cannot judge``: too little texture to tell, and the answer stands on its own
    evidence). ``cause``: the refusal this one replaces (it then names the knock, not its symptom).

    ``quick``: first a look at :data:`QUICK_TILES` tiles spread over the field, judged as a frame's are, and at
    :data:`SECOND_LOOK_TILES` when it cannot judge on an ideal rig (no rectification); its ``healthy`` or
    ``cannot judge`` is returned as it is, and a ``drifted`` is confirmed by the whole check before anything is
    refused (a refusal then stands on the whole check's evidence and false-alarm rate). The whole check refuses
    too when it cannot judge though it reads an offset beyond the tolerance (:func:`suspected_offset`)."""
    if quick:
        # a build's rows are its own rectification's: another camera's frame stands far off them, and the first
        # look tells; on an ideal rig's rows any camera's twins line up but for a few tenths of a px
        for tiles in (QUICK_TILES,) if needs_rectification(rig) else (QUICK_TILES, SECOND_LOOK_TILES):
            look = judge([frame_tiles(check_grey(grey, "image"), rig, near_mm, far_mm, spread=tiles)])
            if look.verdict != "cannot judge":
                break
        if look.verdict != "drifted":
            return look
    check = check_frames([grey], rig, near_mm, far_mm)
    if check.verdict == "drifted":
        raise MeasurementError(check.misfit_words) from cause
    if suspected_offset(check):
        raise MeasurementError(f"whether the rig fits this image cannot be told: {check.reason}; yet the twins do "
                               f"stand off their rows ({check.row_offset_rms_px:.2f} px, more than "
                               f"{SUSPECT_SIGMAS:g} times its uncertainty from none, and above the tolerance as "
                               f"read): no answer through this rig can be shown right (psvs check; psvs refit or "
                               f"calibrate again)") from cause
    return check


#: A field RMS above the tolerance and more than this many times its uncertainty: an offset the check sees
#: though it cannot confirm the tolerance is passed (:func:`suspected_offset`).
SUSPECT_SIGMAS = 3.0


def suspected_offset(check: HealthCheck) -> bool:
    """Whether a check that ``cannot judge`` read the twins off their rows beyond the tolerance and beyond
    :data:`SUSPECT_SIGMAS` of its uncertainty: an offset is there, only its size against the tolerance is not
    pinned. An answer measured through the rig then cannot be shown right (another camera's frame resized to
    the default rig's size: 0.56 +- 0.12 px, and a depth map 41 % trusted at depths 12 % long, an adversarial
    trial). A check short of tiles reads no field (NaN) and suspects nothing."""
    rms, sigma = check.row_offset_rms_px, check.uncertainty_px
    return bool(check.verdict == "cannot judge" and rms > check.tolerance_px and rms > SUSPECT_SIGMAS * sigma)


#: A map trusted on less than this share of its pixels is a weak answer: through a rig, ``psvs disparity`` (when
#: its quick look at the twins could not judge) and the page's dense run then ask the image's whole self-check
#: (:func:`refuse_if_drifted`) whether the rig still fits it. On issue 43's knock the echo weakened to a few
#: percent of the map, and an answer there, or a refusal that blames the scene, would hide the knock. Above it
#: the whole check, which costs about a dense call (1.6 s on 1440 x 1080), is left to ``psvs check`` and the
#: running commands' rolling check.
WEAK_SHARE = 0.10


def whole_check_due(look: HealthCheck, trusted_share: float) -> bool:
    """Whether a dense answer through a rig, after a quick look (:func:`refuse_if_drifted`, ``quick``) that did
    not refuse it, must ask the image's whole check: when the look did not find the rig healthy and the
    answer is weak, trusted on less than :data:`WEAK_SHARE` of the map (0 for an answer refused), where issue
    43's knock left it; and whatever the answer's strength when the look could not judge only because its
    few tiles left the offset within their uncertainty of the tolerance while reading it above (another
    camera's frame resized to this one's size: the look read 0.96 +- 0.28 px, the map was 44 % trusted at
    depths 11 % long, and the whole check reads 0.78 +- 0.11 px, drifted; another such frame, 41 % trusted at
    depths 12 % long: its first look judged 11-12 tiles, reading no field or 0.44 px, its second look 0.58 +-
    0.15 px, and its whole check 0.56 +- 0.12 px, :func:`suspected_offset`). A look that reads no field asks
    nothing more of a strong answer: on a good build's textured 1920 x 1200 frame the whole check would add
    1.6 s to a 2.4 s call."""
    if look.verdict == "healthy":
        return False
    suspected = look.verdict == "cannot judge" and look.row_offset_rms_px > look.tolerance_px   # NaN: no
    return trusted_share < WEAK_SHARE or suspected


def judge(tiles: list[FrameTiles], tolerance_px: float = TOLERANCE_PX, scenes: list[int] | None = None) -> HealthCheck:
    """The field and verdict (module docstring) from the frames' tiles; ``scenes`` (one per frame): which
    frames show the scene as it stood (their tiles' overlaps shared, :func:`evidence_factors`; None: each
    frame its own)."""
    t0 = tiles[0]
    ok = np.concatenate([t.accepted for t in tiles])
    frame_no = np.concatenate([np.full(len(t.accepted), k) for k, t in enumerate(tiles)])[ok]
    frame_of = frame_no if scenes is None else np.asarray(scenes)[frame_no]
    edge = int(np.concatenate([t.at_edge for t in tiles]).sum())
    centre = np.concatenate([t.centre_px for t in tiles])[ok]
    expected = np.concatenate([np.zeros(len(t.accepted)) if t.expected_px is None else t.expected_px
                               for t in tiles])[ok]
    offset = np.concatenate([t.offset_px for t in tiles])[ok] - np.nan_to_num(expected)   # what the rig did not make
    disparity = np.concatenate([t.disparity_px for t in tiles])[ok]
    tried = sum(len(t.accepted) for t in tiles)
    nan, n_nan = float("nan"), np.full(len(offset), np.nan)
    found = dict(row_offset_rms_px=nan, row_offset_max_px=nan, uncertainty_px=nan, scatter_px=nan, judged_px=0,
                 tiles=len(offset), tiles_tried=tried, frames=len(tiles), tolerance_px=float(tolerance_px),
                 grid_shape=t0.grid_shape, centre_px=centre, offset_px=offset, fitted_px=n_nan,
                 coefficients=np.full(6, np.nan), disparity_px=disparity, expected_px=np.nan_to_num(expected))
    repeating = int(sum(int(t.repeating.sum()) for t in tiles if t.repeating is not None))
    ridged = int(sum(int(t.ridged.sum()) for t in tiles if t.ridged is not None))
    if len(offset) < MIN_TILES and ridged > max(len(offset), repeating):
        return HealthCheck("cannot judge", f"the texture runs along one direction: {ridged} tiles match about as "
                           f"well on other rows as on their peak's, {len(offset)} do not (needs {MIN_TILES}; a "
                           "streak or an edge shifted along itself tells no row): frames of a scene textured in "
                           "every direction are needed", **found)
    if repeating > edge + len(offset):
        return HealthCheck("cannot judge", f"the texture repeats along the rows: {repeating} tiles match about as "
                           f"well away from their best peak as at it, {edge + len(offset)} do not (a repeating "
                           "texture tells no twin's row): frames of a scene whose texture does not repeat are needed",
                           **found)
    if edge >= max(MIN_TILES, EDGE_SHARE * (edge + len(offset))):
        found.update(row_offset_rms_px=float(t0.reach_px), row_offset_max_px=float(t0.reach_px))
        return HealthCheck("drifted", f"the twins of {edge} tiles lie {t0.reach_px} rows or more off their rows, "
                           f"as far as the check searches: the rig has moved far more than the tolerance", **found)
    if len(offset) < MIN_TILES:
        return HealthCheck("cannot judge", f"only {len(offset)} of {tried} tiles show a twin above chance (needs "
                           f"{MIN_TILES}): frames of a textured scene filling more of the field, over the working "
                           f"range, are needed (or the scene lies outside the range as this calibration sees "
                           f"it: a rig far off puts a wall's twins past the disparities searched)", **found)
    places = t0.places_px if t0.places_px is not None and len(t0.places_px) else _grid_corners(t0.grid_shape)
    regions = covered_regions(centre, places)
    if regions < MIN_REGIONS:
        return _bunched(len(offset), regions, found)
    A = field_basis(centre, t0.grid_shape)
    bound = curvature_bound_px(t0.grid_shape, t0.focal_px)
    coef, inliers, scatter = robust_fit(A, offset, bound)
    n = int(inliers.sum())
    refused = _not_one_field(A, coef, inliers, scatter, frame_no, places, found, bound)
    if refused is not None:
        return refused
    at, rms, unc, dof, repeat = _figures(A[inliers], offset[inliers], coef, scatter, centre[inliers],
                                         frame_of[inliers], t0.size_px)
    top = float(np.abs(at).max())
    judged = n * t0.size_px ** 2
    found.update(row_offset_rms_px=rms, row_offset_max_px=top, uncertainty_px=unc, scatter_px=scatter,
                 judged_px=judged, tiles=n, centre_px=centre[inliers], offset_px=offset[inliers], fitted_px=at,
                 coefficients=coef, disparity_px=disparity[inliers], expected_px=np.nan_to_num(expected)[inliers])
    evidence = (f"{n} tiles ({judged} px) of {len(tiles)} frame(s), field RMS {rms:.2f} +- {unc:.2f} px, "
                f"largest {top:.2f} px, tolerance {tolerance_px:g} px")
    k = _two_sigma(dof)
    if rms + k * unc <= tolerance_px:
        return HealthCheck("healthy", f"the twins stand on their rows: {evidence}", **found)
    if rms - k * unc > tolerance_px:
        few = _rests_on_few(A[inliers], offset[inliers], bound, unc ** 2, tolerance_px)
        if few:
            return HealthCheck("cannot judge", f"the offset rests on a few tiles: {evidence}, but {few}; more "
                               "frames decide it", **found)
        return HealthCheck("drifted", f"the twins stand off their rows: {evidence}", **found)
    more = "frames of the scene moved, or of other scenes," if repeat > 1.5 else "more frames"
    return HealthCheck("cannot judge", f"the offset is within its uncertainty of the tolerance: {evidence}; {more} "
                       f"decide it", **found)


def tile_noise_px(scatter_px: float, n: int, p: int) -> float:
    """A tile's noise (px) from the robust ``scatter_px`` of ``n`` tiles' residuals about a fit of ``p`` terms: those
    residuals have n - p degrees of freedom, so their spread understates the noise by sqrt((n - p) / n) (at the
    12 tiles of a first judgement, by 30 %)."""
    return float(scatter_px * math.sqrt(n / max(n - p, 1)))


def _figures(A: np.ndarray, y: np.ndarray, coef: np.ndarray, scatter: float, centre: np.ndarray, scene: np.ndarray,
             size_px: int) -> tuple[np.ndarray, float, float, int, float]:
    """(the field at the tiles (n,), its RMS, its uncertainty px, the degrees of freedom, the repeat factor) of the
    field ``coef`` (6,) fitted to tiles (basis rows A (n, 6), offsets ``y`` (n,), centres (n, 2), ``scene`` (n,),
    side ``size_px``) whose residuals scatter by ``scatter`` px (robust sigma): the module docstring's figures."""
    n, p = A.shape
    fitted = A @ coef
    overlap, repeat = evidence_factors(centre, scene, y - fitted, size_px)
    dof = int(n / (overlap * repeat)) - p
    noise = tile_noise_px(scatter, n, p)
    cov = overlap * repeat * noise ** 2 * np.linalg.pinv(A.T @ A)
    var = np.einsum("ij,jk,ik->i", A, cov, A)
    unc = float(np.sqrt(np.mean(var)))
    rms = float(np.sqrt(max(np.mean(fitted ** 2) - np.mean(var), 0.0)))   # noise adds its variance to the mean square
    return fitted, rms, unc, dof, repeat


#: A drift must stand with this many of its tiles left out, those that bear it most: wrong twins (a chance
#: peak, the other view's texture) come a few at a time, and among few tiles a field passes through them (a CI
#: run's undrifted build: 3 of 15 tiles 3.7-4.9 px off, read as a drift of 2.05 +- 0.39 px).
SPARE_TILES = 3


def _rests_on_few(A: np.ndarray, y: np.ndarray, bound: np.ndarray, var: float, tolerance_px: float) -> str:
    """What says a drift (the field of tiles A (n, 6), offsets ``y`` (n,), its coefficients within ``bound``, the
    fit's mean variance ``var`` px^2 at the tiles) rests on a few of its tiles ('' it does not): with the
    :data:`SPARE_TILES` tiles that bear it most left out, one at a time (each time the one without which the
    field's mean square over all n tiles is least: the least-squares fit's closed-form leave-one-out), the field
    refitted and read over all n tiles as the verdict read it (the noise variance off) is within the tolerance.
    Its uncertainty was judged on all the tiles: this asks only whether the offset is theirs or a few tiles'.
    Each tile left out moves a field of many tiles by its share of the evidence (its leverage, about p/n, times
    its residual): a verdict on many tiles does not fall (drawn fields 0.9 px on 60 and 120 tiles: as many
    drifted verdicts as without this test)."""
    n, p = A.shape
    keep = np.ones(n, bool)
    for m in range(1, SPARE_TILES + 1):
        if keep.sum() <= p + 1:
            return f"with {m - 1} of them left out no field is pinned by the {int(keep.sum())} left"
        a, b = A[keep], y[keep]
        g = np.linalg.pinv(a.T @ a)
        c = g @ a.T @ b
        h = np.einsum("ij,jk,ik->i", a, g, a)
        without = c[None, :] - (a @ g) * ((b - a @ c) / np.maximum(1.0 - h, 1e-9))[:, None]   # (kept, 6)
        keep[np.flatnonzero(keep)[int(np.argmin(np.mean((without @ A.T) ** 2, axis=1)))]] = False
        rms = math.sqrt(max(float(np.mean((A @ bounded_lstsq(A[keep], y[keep], bound)) ** 2)) - var, 0.0))
        if rms <= tolerance_px:
            return f"with the {m} tile(s) that bear it most left out the field reads {rms:.2f} px over them all"
    return ""


def evidence_factors(centres_px: np.ndarray, scene: np.ndarray, residuals_px: np.ndarray,
                     size_px: int) -> tuple[float, float]:
    """(overlap, repeat): by how much the count of tiles (centres (n, 2), ``scene`` (n,) the view of the scene
    each was read in, residuals (n,) px about the field, side ``size_px``) overstates their independent
    evidence. Overlapping tiles share pixels, so their errors are not independent: the evidence is the area
    they cover, in tiles, each scene's tiles' union counted once (frames of a scene that stood still share
    one: a neighbour read in the next frame shares its texture as one in the same frame does). The same place
    in several frames counted apart, whether the scene stood still is measured too (:func:`repeat_factor`: the
    same place's errors repeat in a still scene and count once)."""
    n = len(residuals_px)
    return n / independent_tiles(centres_px, scene, size_px), repeat_factor(centres_px, residuals_px)


def _not_one_field(A: np.ndarray, coef: np.ndarray, inliers: np.ndarray, scatter: float, frame: np.ndarray,
                   places: np.ndarray, found: dict, bound: np.ndarray) -> HealthCheck | None:
    """``cannot judge`` when the fitted field (basis rows A (n, 6) of the tiles ``found['centre_px']``, their
    offsets ``found['offset_px']``; its ``coef`` (6,), ``inliers`` and ``scatter`` px; ``frame`` (n,) each
    tile's frame; ``bound`` (6,) the coefficients' bounds) is not the tiles' one field: too few or too
    scattered on it, a second field among those left out
    (:func:`_another_field`), or its tiles bunched in fewer than :data:`MIN_REGIONS` of the frame's ninths
    (``places`` (m, 2)). None: it is."""
    n, m = int(inliers.sum()), len(inliers)
    if n < MIN_TILES or scatter > MAX_SCATTER_PX or n < MIN_CONSISTENT * m:
        return HealthCheck("cannot judge", f"the {m} tiles above chance disagree with any smooth field (scatter "
                           f"{scatter:.2f} px, at most {MAX_SCATTER_PX:g} allowed; {n} of {m} on it, "
                           f"{max(MIN_TILES, math.ceil(MIN_CONSISTENT * m))} needed): the frames do not show one "
                           "rig's twins; frames of a still, textured scene are needed", **found)
    apart = _another_field(A, coef, inliers, frame, places, found, bound, tile_noise_px(scatter, n, A.shape[1]))
    if apart:
        return HealthCheck("cannot judge", f"the tiles above chance hold two fields: {apart}: frames of one rig, "
                           "as it stands now, are needed", **found)
    regions = covered_regions(found["centre_px"][inliers], places)
    return _bunched(n, regions, found) if regions < MIN_REGIONS else None


def _another_field(A: np.ndarray, main: np.ndarray, inliers: np.ndarray, frame: np.ndarray, places: np.ndarray,
                   found: dict, bound: np.ndarray, noise_px: float) -> str:
    """What says the tiles (:func:`_not_one_field`'s) hold a second field the fit left out ('' none): a whole
    frame (:data:`MIN_TILES` or more tiles over :data:`MIN_REGIONS` of its ninths) whose tiles mostly lie off
    the field (a frame of the rig before or after a knock, or of another rig, beside the others) or whose tiles
    on it stand apart from it as a field of their own (:func:`frame_apart`; ``noise_px`` a tile's noise about
    the field), or left-out tiles (a quarter of them all and :data:`MIN_TILES` or more) that mostly lie on one
    smooth field of their own, apart from the fitted one by more than the tolerance. Wrong tiles scatter; a
    moved rig's lie on a field."""
    y, centre, tolerance_px = found["offset_px"], found["centre_px"], found["tolerance_px"]
    frames = np.unique(frame)
    # the frames' common field unbounded (the fit's is held to the curvature a turned view makes: what lies
    # beyond that bound is every frame's, not one frame's own)
    common = np.linalg.lstsq(A[inliers], y[inliers], rcond=None)[0] if len(frames) > 1 else main
    for k in frames:
        at = frame == k
        whole = at.sum() >= MIN_TILES and covered_regions(centre[at], places) >= MIN_REGIONS
        if whole and inliers[at].mean() < MIN_CONSISTENT:
            return (f"{int((~inliers[at]).sum())} of frame {int(k) + 1}'s {int(at.sum())} tiles lie off the field "
                    f"the others hold")
        on = at & inliers
        if len(frames) > 1 and whole and on.sum() >= MIN_TILES:
            gap, chi2 = frame_apart(A[on], y[on] - A[on] @ common, noise_px)
            if gap > 0.5 * tolerance_px and chi2 > CHI2_APART:
                return (f"frame {int(k) + 1}'s {int(on.sum())} tiles stand {gap:.2f} px RMS off the field of them "
                        f"all (chi-square {chi2:.0f}, beyond {CHI2_APART:g})")
    out = ~inliers
    if out.sum() < max(MIN_TILES, 0.25 * len(y)):
        return ""
    coef, on, scatter = robust_fit(A[out], y[out], bound)
    if on.mean() < 0.8 or scatter > MAX_SCATTER_PX:
        return ""
    gap = float(np.sqrt(np.mean((A[out][on] @ (coef - main)) ** 2)))
    if gap <= tolerance_px:
        return ""
    return f"{int(on.sum())} tiles left out lie on a field of their own, {gap:.2f} px RMS apart"


#: The 99.9 % point of a chi-square of 6 degrees of freedom (the field's terms): a frame's own field apart from
#: the field of all the frames by more is another state of the rig. One rig's frames of walls, photos, the
#: textured scene and Fig. 6 read at most 14 here (a frame of another state beside them 80-107: the rig
#: leaned 0.025 deg between them, 0.71 px).
CHI2_APART = 22.46


def frame_apart(A: np.ndarray, residual_px: np.ndarray, noise_px: float) -> tuple[float, float]:
    """(gap px, chi-square): how far the field of one frame's tiles (basis rows A (n, 6), their ``residual_px``
    (n,) about the field of all the frames) stands from that field, RMS over its tiles, and the chi-square of its
    6 terms given a tile's noise ``noise_px`` and the tiles' :data:`OVERLAP` (a whole frame's: each pixel in that
    many tiles)."""
    normal = A.T @ A
    delta = np.linalg.pinv(normal) @ A.T @ residual_px
    gap = float(np.sqrt(np.mean((A @ delta) ** 2)))
    chi2 = float(delta @ normal @ delta) / (OVERLAP * max(noise_px, 1e-9) ** 2)
    return gap, chi2


def _bunched(n: int, regions: int, found: dict) -> HealthCheck:
    """``cannot judge``: ``n`` tiles in only ``regions`` of the frame's ninths."""
    return HealthCheck("cannot judge", f"the {n} tiles on one field lie in {regions} of the frame's 9 regions (needs "
                       f"{MIN_REGIONS}): frames of a textured scene filling more of the field, over the working "
                       f"range, are needed", **found)


def _grid_corners(grid_shape: tuple[int, int]) -> np.ndarray:
    """The corners (2, 2) of a grid (H', W'): the extent tiles stand in when their places are not given."""
    h, w = grid_shape
    return np.array([[0.0, 0.0], [w - 1.0, h - 1.0]])


def covered_regions(centres_px: np.ndarray, places_px: np.ndarray) -> int:
    """In how many of the 3 x 3 regions of the places a tile can stand (``places_px`` (m, 2), split evenly over
    their extent in u' and v') the tiles at ``centres_px`` (n, 2) lie."""
    lo, hi = places_px.min(axis=0), places_px.max(axis=0)
    cell = np.clip(np.floor(3.0 * (centres_px - lo) / np.maximum(hi - lo, 1e-9)), 0, 2).astype(int)
    return len({(int(a), int(b)) for a, b in cell})


def independent_tiles(centres_px: np.ndarray, frame: np.ndarray, size_px: int) -> float:
    """How many tiles' worth of pixels the tiles at ``centres_px`` (n, 2) of frames ``frame`` (n,) cover, each
    frame's overlapping tiles (side ``size_px``, on a lattice of half their side) counted once: their union's
    area over a tile's, summed over the frames."""
    half = max(size_px // 2, 1)
    corner = np.floor((centres_px - 0.5 * (size_px - 1)) / half + 0.5).astype(int)     # in half-tile cells
    pairs = zip(frame.tolist(), corner.tolist(), strict=True)
    cells = [(f, c[0] + i, c[1] + j) for f, c in pairs for i in (0, 1) for j in (0, 1)]
    return len(set(cells)) / 4.0


def repeat_factor(centres_px: np.ndarray, residuals_px: np.ndarray) -> float:
    """How many times (>= 1) the tiles' count overstates their independent evidence: tiles at the same place
    (``centres_px`` (n, 2), equal) in several frames share the error their texture makes when the scene stands
    still. From the residuals (n,) px about the field, a one-way analysis of variance by place: the intraclass
    correlation rho = (MSB - MSW) / (MSB + (n0 - 1) MSW) (between- and within-place mean squares, n0 the
    places' effective size; clipped to 0..1), and the count's design effect n / sum_i n_i / (1 + (n_i - 1) rho)
    over the places' counts n_i. One frame, or frames of a scene that moves: about 1; one frame repeated: the
    number of frames."""
    _, place, counts = np.unique(centres_px, axis=0, return_inverse=True, return_counts=True)
    place = place.ravel()
    n, k = len(residuals_px), len(counts)
    if counts.max() < 2:
        return 1.0
    if k < 2:
        return float(n)                       # one place seen n times: one piece of evidence
    means = np.bincount(place, residuals_px) / counts
    msw = float(np.sum((residuals_px - means[place]) ** 2)) / (n - k)
    msb = float(np.sum(counts * (means - residuals_px.mean()) ** 2)) / (k - 1)
    n0 = (n - float(np.sum(counts ** 2)) / n) / (k - 1)
    den = msb + (n0 - 1.0) * msw
    rho = float(np.clip((msb - msw) / den, 0.0, 1.0)) if den > 0 else 1.0
    return float(n / np.sum(counts / (1.0 + (counts - 1) * rho)))


def _two_sigma(dof: int) -> float:
    """The multiple of a standard error estimated with ``dof`` degrees of freedom that holds what two sigmas of a
    known one do (97.7 % one-sided): Student's t quantile (2.52 at 6, 2.0 as they grow)."""
    from scipy.special import stdtrit  # scipy.stats' t.ppf, without its second of import
    return float(stdtrit(max(dof, 1), 0.5 * math.erfc(-2.0 / math.sqrt(2.0))))


def load_solvers() -> None:
    """Import the fit's and the verdict's SciPy modules now (half a second the first time in a process): the
    rolling check's set-up, kept out of its steps' measured cost (:mod:`psvs.health.rolling`)."""
    import scipy.optimize  # noqa: F401
    import scipy.special  # noqa: F401
