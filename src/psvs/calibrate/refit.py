"""Re-fit a drifted calibration from ordinary frames, and tare its depth on flat surfaces at known distances
(``psvs refit``; docs/health.md).

**The evidence.** The self-check (:mod:`psvs.health`) finds each textured tile's twin where it is, within
its reach, not where the calibration expects it: every judged tile is a pair of complex-image pixels, the
left view's and the right view's image of one scene point (:func:`psvs.health.check.judged_pairs_px`).

**The rows.** Which rig puts every pair on one scene point? A bundle adjustment in which each point is free:
for a trial rig, each pair is triangulated over the exact optics (:func:`psvs.measure.triangulate.triangulate`,
the point eliminated) and reprojected into both views; the residuals are the reprojections minus the pair
(4 per pair, px). A pair's free point absorbs its position and depth, so each pair pins one number: how far
its twins stand off their rows. The rows' unknowns are the mirrors' tilts out of vertical (b), which move
a view across its rows.

**The depth** (:mod:`psvs.calibrate.tare`). The mirrors' turns about the vertical (a) move a view along its
rows: only depth sees them. Each tare adds its tiles' depths off its plane; its distance pins the depth's
offset there, and two tares at two distances its scale as well.

**What is held.** Everything else (the lens, the plate, the baseline, the mirrors' shifts: what only a
target or a known length pins, and none of which a knock moves as it tilts glass) stays at the old
calibration (:data:`HELD_PARAMS`). Each refitted tilt has a prior about its old value
(:data:`DRIFT_SIGMA_RAD`: what knocks and creep do), and each stage fits only the combinations its data
pin to under :data:`UNPINNED` of their prior's sigma (truncated Gauss-Newton, :func:`_fit`): a combination
the data barely see would be moved by the tiles' noise alone. The rest keep their old values and the result
names them ("what no frame could pin"), with the depth's 1 sigma they leave on the axis over the working range.

**Weights and 1 sigma.** A view's residual is weighed by the tiles' scatter about the check's field
(:attr:`psvs.health.check.HealthCheck.scatter_px`, split between the views, the tiles' overlap
:data:`psvs.health.check.OVERLAP` counted); each change has its Gauss-Newton 1 sigma. Two rounds: the frames
are read again through the first round's rig (the tiles then search about the twins' new rows) and fitted
again, priors still about the old calibration.

**Right or refused** (:class:`psvs.errors.MeasurementError`): frames the check cannot judge, twins beyond
its reach, a tare it cannot read or that is not flat, and a refit after which the twins still stand off their
rows (something moved that the mirrors' tilts do not explain, e.g. the lens: calibrate again).
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from psvs.calibrate.bundle import PRIOR_SIGMA, rig_from_values, rig_values
from psvs.calibrate.tare import MIN_TARE_SIGMA_MM, TARE_SIGMA_MM, Tare, check_flat, depth_residuals_px, tare_record
from psvs.errors import MeasurementError, RigGeometryError
from psvs.health.check import OVERLAP, HealthCheck, check_frames, judged_pairs_px
from psvs.io.jsonsafe import json_safe
from psvs.measure.triangulate import triangulate
from psvs.optics.layout_check import check_clear
from psvs.optics.mirrors import virtual_baseline_mm
from psvs.optics.project import project_points
from psvs.optics.rig import Calibration, Rig

#: What frames re-fit: the mirror tilts (rad), as psvs.calibrate.bundle names them.
REFIT_PARAMS = tuple(f"m{k}_tilt_{a}_rad" for k in range(1, 5) for a in "ab")
#: What a refit holds at the old calibration (all of psvs.calibrate.bundle's other parameters).
HELD_PARAMS = tuple(p for p in PRIOR_SIGMA if p not in REFIT_PARAMS)
#: The rows' stage fits the tilts out of vertical (b), which move a view across its rows; the depth's stage
#: (the tares) the turns about the vertical (a), which move it along its rows.
ROW_PARAMS = tuple(k for k, p in enumerate(REFIT_PARAMS) if "tilt_b" in p)
DEPTH_PARAMS = tuple(k for k, p in enumerate(REFIT_PARAMS) if "tilt_a" in p)
#: The prior on each tilt's change since the calibration (rad): what a knock or a warm week does to glued glass.
DRIFT_SIGMA_RAD = math.radians(0.1)
#: The largest change of a tilt a refit gives (rad): ten of the prior's sigmas. A knock that turned glass
#: further moved more than tilts (calibrate again); a refit that wants more is driven by a tare whose stated
#: distance is not where the surface was (a tare 50 mm off turned every mirror by 4 deg).
MAX_CHANGE_RAD = math.radians(1.0)
#: A refit whose tares' turns fit the frames' twins worse than the calibration's turns do, by more than chance
#: gives at this level (a chi-square of as many degrees of freedom as the tares pin), is refused: the tares'
#: stated distances disagree with the frames (:func:`_check_tares_agree`).
TARE_AGREE_LEVEL = 0.999
#: Rounds of reading the frames and fitting.
ROUNDS = 2
#: Each stage iterates at most ITERATIONS times, until no step exceeds STEP_DONE of a prior sigma.
ITERATIONS = 6
STEP_DONE = 1e-4
#: A combination of the tilts whose posterior sigma is over this share of its prior's is not pinned.
UNPINNED = 0.5
#: Residuals beyond this many sigmas weigh less (soft-L1): a tile across a depth edge is no one point.
LOSS_SIGMAS = 2.0
#: The smallest scatter (px) a tile's offset is weighed with (a perfect render would weigh without bound).
MIN_SCATTER_PX = 0.02
#: A pair the trial rig cannot triangulate or project: this residual (in sigmas) per component.
_MISS = 10.0
#: The finite-difference step of the Jacobian (rad).
_STEP = 1e-6


@dataclass(frozen=True)
class Refit:
    """A refit: the new ``rig``; ``change`` (tilt as named in files -> (old, new, 1 sigma) deg);
    ``unpinned`` the combinations no frame could pin (held near the old values by their priors;
    :func:`unpinned_combinations`), ``scale_sigma`` the depth scale's relative 1 sigma they leave (the
    baseline |O1 O2|'s) and ``depth_sigma`` the depth's on the axis ((Z mm, relative 1 sigma) at the working
    range's ends and middle: :func:`depth_sigma`, the offset as well as the scale); ``rms_px`` the pairs'
    reprojection RMS; ``pairs`` used (``tare_pairs`` of them from the tares) of ``frames``; the check ``before``
    (old rig) and ``after`` (new rig) on the frames; ``tares`` (:class:`psvs.calibrate.tare.Tare`, one per
    tare); ``message`` (how the fit ended); ``tare_sigma_mm`` the 1 sigma each tare's stated distance was
    taken with (part of the sigmas above)."""

    rig: Rig
    change: dict[str, tuple[float, float, float]]
    unpinned: tuple[tuple[tuple[str, float], ...], ...]
    scale_sigma: float
    depth_sigma: tuple[tuple[float, float], ...]
    rms_px: float
    pairs: int
    tare_pairs: int
    frames: int
    before: HealthCheck = field(repr=False)
    after: HealthCheck = field(repr=False)
    tares: tuple[Tare, ...]
    message: str
    tare_sigma_mm: float = 0.0

    def as_dict(self) -> dict:
        """The record of the refit as JSON-ready values (NaN as None; written beside the rig file by
        ``psvs refit``)."""
        rows = lambda c: {"verdict": c.verdict, "row_offset_rms_px": c.row_offset_rms_px,  # noqa: E731
                          "uncertainty_px": c.uncertainty_px, "tiles": c.tiles}
        return json_safe({"frames": self.frames, "pairs": self.pairs, "tare_pairs": self.tare_pairs,
                          "reprojection_rms_px": self.rms_px, "fit": self.message,
                          "rows_before": rows(self.before), "rows_after": rows(self.after),
                          "held": sorted(_file_name(p) for p in HELD_PARAMS),
                          "unpinned": [dict(c) for c in self.unpinned], "depth_scale_sigma": self.scale_sigma,
                          "depth_sigma": [{"z_mm": z, "sigma": s} for z, s in self.depth_sigma],
                          "change": {p: {"old": o, "new": n, "sigma": s} for p, (o, n, s) in self.change.items()},
                          "tares": [dataclasses.asdict(t) for t in self.tares],
                          "tare_sigma_mm": self.tare_sigma_mm})


def _file_name(p: str) -> str:
    """A parameter's name in files: tilts in degrees (``m3_tilt_b_deg``)."""
    return p[:-4] + "_deg" if p.endswith("_rad") else p


@dataclass(frozen=True)
class _Pairs:
    left: np.ndarray       # (n, 2) complex-image px
    right: np.ndarray
    source: np.ndarray     # (n,) -1: a frame's; k: tare k's
    sigma_px: float        # a view's residual's weight


def refit_rig(frames, rig: Rig, tares=(), near_mm: float = 400.0, far_mm: float = 1200.0,
              tolerance_px: float = 0.5, tare_sigma_mm: float = TARE_SIGMA_MM) -> Refit:
    """Re-fit ``rig``'s mirror tilts from ordinary ``frames`` (list of (H, W) grey images) and ``tares``
    ((image (H, W), distance mm along the axis from the optical centre O) each: a flat textured surface facing
    the rig, each distance known to ``tare_sigma_mm``, 1 sigma), module docstring. MeasurementError when the
    frames cannot give a right answer."""
    if not (math.isfinite(tare_sigma_mm) and tare_sigma_mm >= MIN_TARE_SIGMA_MM):
        raise ValueError(f"a tare's distance sigma must be a length of at least {MIN_TARE_SIGMA_MM:g} mm (no "
                         f"surface's distance from the optical centre is known exactly), got {tare_sigma_mm}")
    tares = [(img, float(z)) for img, z in tares]
    for _, z in tares:
        if not (math.isfinite(z) and near_mm <= z <= far_mm):
            raise ValueError(f"a tare's distance must lie in the working range {near_mm:g}-{far_mm:g} mm, got {z:g}")
    _check_distinct_tares([img for img, _ in tares])
    before = check_frames(frames, rig, near_mm, far_mm, tolerance_px)
    new, x, pairs, steps = rig, np.zeros(len(REFIT_PARAMS)), None, []
    cov = np.diag(np.full(len(REFIT_PARAMS), DRIFT_SIGMA_RAD ** 2))
    distances = tuple(z for _, z in tares)
    rows_only = None
    for k in range(ROUNDS):
        read = before if k == 0 else check_frames(frames, new, near_mm, far_mm, tolerance_px)
        pairs = _read_pairs(read, [img for img, _ in tares], new, near_mm, far_mm, tolerance_px)
        if k == 0 and tares:            # the frames' own rows' answer: a tare of another state must not steer it
            rows_only = _fit(_Stage(rig, _frames_only(pairs), x, ROW_PARAMS))[0]
            _check_tares_rows([img for img, _ in tares], _rig(rows_only, rig), near_mm, far_mm, tolerance_px)
        x, c, n_rows = _fit(_Stage(rig, pairs, x, ROW_PARAMS))
        cov[np.ix_(ROW_PARAMS, ROW_PARAMS)] = c
        steps = [n_rows]
        if tares:
            pairs = _on_tare_planes(x, rig, pairs, distances)
            x, c, n_depth = _fit(_Stage(rig, pairs, x, DEPTH_PARAMS, distances, tare_sigma_mm))
            cov[np.ix_(DEPTH_PARAMS, DEPTH_PARAMS)] = c
            steps.append(n_depth)
        new = _rig(x, rig)
    _check_changes(x, rig, new, distances)
    after = check_frames(frames, new, near_mm, far_mm, tolerance_px)
    if tares:                   # before the verdict: a wrong distance explains a drifted one
        _check_tares_agree(x, cov, rig, _frames_only(pairs), distances,
                           lambda: (after, check_frames(frames, _rig(rows_only, rig), near_mm, far_mm, tolerance_px)))
    if tares:                   # the distances agree with the frames: is the knock within what the prior holds?
        _check_prior_holds(x, cov, distances)
    if after.verdict == "drifted":
        raise MeasurementError(f"after the refit the twins still stand off their rows ({after.reason}): what moved "
                               f"is more than the mirrors' tilts; calibrate again from card views (psvs calibrate)")
    if after.verdict != "healthy":
        raise MeasurementError(f"the frames cannot show the refitted rig healthy ({after.reason}): more frames of a "
                               f"textured scene are needed")
    sigma = np.sqrt(np.clip(np.diag(cov), 0, None))
    old = rig_values(rig)
    change = {_file_name(p): (math.degrees(old[p]), math.degrees(old[p] + d), math.degrees(s))
              for p, d, s in zip(REFIT_PARAMS, x, sigma, strict=True)}
    res = _points(x, rig, pairs)[2]
    rms = float(np.sqrt(np.nanmean(res ** 2)))
    message = f"{steps[0]} Gauss-Newton step(s) on the rows" + (
        f", {steps[1]} on the tares' depth" if tares else "") + f" (the last of {ROUNDS} rounds)"
    return Refit(dataclasses.replace(new, calibration=_record(rig, rms, len(frames), distances)), change,
                 unpinned_combinations(cov), scale_sigma(new, cov),
                 depth_sigma(new, cov, (near_mm, 0.5 * (near_mm + far_mm), far_mm)), rms, len(pairs.left),
                 int((pairs.source >= 0).sum()), len(frames), before, after, _tares(pairs, rig, new, distances),
                 message, float(tare_sigma_mm) if tares else 0.0)


def _check_changes(x: np.ndarray, old: Rig, new: Rig, distances) -> None:
    """MeasurementError when a refitted tilt changed by more than :data:`MAX_CHANGE_RAD`, or the refitted
    layout is blocked (no build has it: :func:`psvs.optics.layout_check.check_clear`)."""
    worst = int(np.argmax(np.abs(x)))
    tares = f" (the tares at {', '.join(f'{z:g}' for z in distances)} mm: is each where its surface was?)" \
        if distances else ""
    if abs(x[worst]) > MAX_CHANGE_RAD:
        raise MeasurementError(f"the refit would turn {_file_name(REFIT_PARAMS[worst])} by "
                               f"{math.degrees(x[worst]):+.2f} deg, more than a knock does (at most "
                               f"{math.degrees(MAX_CHANGE_RAD):g} deg){tares}: calibrate again from card views")
    try:
        check_clear(new, "the refitted rig")
    except RigGeometryError as exc:
        raise MeasurementError(f"{exc}{tares}") from None


def _check_prior_holds(x: np.ndarray, cov: np.ndarray, distances) -> None:
    """MeasurementError when the tares' depth asks the turns about the vertical to change by more than the prior
    (:data:`DRIFT_SIGMA_RAD` each) lets a knock do, while some combination of them no tare pins is held to that
    prior: the knock was larger than the prior says, those combinations may have moved as far, and the depth
    sigma the prior gives them would be stated too small. The pinned change's chi^2 in the prior's units
    against its 99.9 % point for as many degrees of freedom as the tares pin. (An adversarial trial: M1 of the
    misaligned build turned 0.8 deg about the vertical, refit with one tare, changed the four turns by 0.21 deg
    each (4.2 of the prior's sigmas in all) and stated depth to 0.26 % at 1200 mm; a wall at 1150 mm read
    1.05 % off through it, a wall at 450 mm 0.26 % against 0.09.)"""
    from scipy.stats import chi2
    k = list(DEPTH_PARAMS)
    z = x[k] / DRIFT_SIGMA_RAD
    pinned = _pinned(cov)
    if pinned == 0 or pinned == len(k):         # nothing pinned, or every turn pinned by the tares themselves
        return
    pull = float(z @ z)
    if pull > chi2.ppf(0.999, pinned):
        raise MeasurementError(
            f"the tares' depth asks the mirrors' turns about the vertical to change by "
            f"{math.degrees(float(np.sqrt(np.sum(x[k] ** 2)))):.2f} deg in all, {np.sqrt(pull):.1f} times what a "
            f"knock does ({math.degrees(DRIFT_SIGMA_RAD):g} deg a turn), while {len(k) - pinned} combination(s) of "
            f"them no tare pins are held to that: they may have moved as far, and the depth would be off by more "
            f"than stated (the tares at {', '.join(f'{d:g}' for d in distances)} mm): calibrate again from card "
            "views (psvs calibrate)")


def _check_distinct_tares(images) -> None:
    """ValueError when two tares are the same image: one surface seen once is one tare's evidence, however often
    it is given (an adversarial trial: the same tare given twice doubled its pairs and narrowed the stated depth
    sigma, and an image stated at two distances is no tare at all)."""
    seen: dict[bytes, int] = {}
    for k, img in enumerate(images):
        a = np.ascontiguousarray(img)
        key = hashlib.sha256(a.tobytes() + repr((a.shape, a.dtype.str)).encode()).digest()
        if key in seen:
            raise ValueError(f"tare {k + 1} is the same image as tare {seen[key] + 1}: one image of a surface is one "
                             "tare, however often it is given (a second tare is another image, at another distance)")
        seen[key] = k


def _check_tares_rows(images, rows_rig: Rig, near_mm, far_mm, tolerance_px) -> None:
    """MeasurementError when a tare's own twins stand off their rows under the frames' own rows' refit
    (``rows_rig``): it shows another state of the rig than the frames (a tare taken before a knock, an adversarial
    trial: its refusal blamed the rig, 'calibrate again')."""
    for k, img in enumerate(images):
        c = check_frames([img], rows_rig, near_mm, far_mm, tolerance_px)
        if c.verdict == "drifted":
            raise MeasurementError(f"tare {k + 1} shows another state of the rig than the frames: under their refit "
                                   f"its twins stand off their rows ({c.reason}); was it taken before a knock? take "
                                   "it again after the frames, or the frames again with it")


def _check_tares_agree(x: np.ndarray, cov: np.ndarray, old: Rig, frames: _Pairs, distances, fields) -> None:
    """MeasurementError when the turns about the vertical the tares' depth asks (in the change ``x``) fit the
    ``frames``' twin pairs worse than the calibration's own turns do, beyond chance: a likelihood-ratio test on the
    same pairs, each side at its best tilts out of vertical (:func:`_rows_cost`), against the
    :data:`TARE_AGREE_LEVEL` point of the chi-square with as many degrees of freedom as the tares pin. A tare at
    its true distance asks the turns the frames were taken with, which put the twins on their rows at least as
    well as the old turns (a knock about the vertical moves the rows too, a little); a distance stated wrongly
    asks turns no frame shows, and the rows say so. Over three knocks and three seeds (three walls, 588 pairs)
    the right distances gave -7.3 to +0.5 against the limit's 10.8 (one tare; 13.8 for two), a tare 20 mm off
    13-65. (Before: the fields' RMS compared, 3 of their sigmas and 0.1 px, and an adversarial trial's tare
    at 600 mm stated as 556, taped from the rig's front, was taken: the twins 0.20 +- 0.04 px off their rows
    against 0.04, within the sigmas of two fields of the same tiles, whose noise is common to both; depth 5-13 %
    off, stated to 0.1-0.3 %.) ``fields`` gives (the check after the refit, the check under the rows' own answer)
    for the message, only when refused."""
    from scipy.stats import chi2
    calibrated = x.copy()
    calibrated[list(DEPTH_PARAMS)] = 0.0
    worse = _rows_cost(x, old, frames) - _rows_cost(calibrated, old, frames)
    limit = float(chi2.ppf(TARE_AGREE_LEVEL, max(_pinned(cov), 1)))
    if worse <= limit:
        return
    after, rows_only = fields()
    raise MeasurementError(
        "the tares disagree with the frames: the turns their depth asks put the twins "
        f"{after.row_offset_rms_px:.2f} +- {after.uncertainty_px:.2f} px off their rows, "
        f"{rows_only.row_offset_rms_px:.2f} +- {rows_only.uncertainty_px:.2f} px without them, a fit worse by a "
        f"chi-square of {worse:.1f} over the frames' {len(frames.left)} tiles where chance gives up to {limit:.1f} "
        f"(the tares at {', '.join(f'{z:g}' for z in distances)} mm: is each where its surface was, measured "
        "from the optical centre O?)")


def _rows_cost(x: np.ndarray, old: Rig, pairs: _Pairs) -> float:
    """The soft-L1 cost (:data:`LOSS_SIGMAS`; a residual r in sigmas costs about r^2 while small) of ``pairs``'
    reprojection under the change ``x`` with its tilts out of vertical re-fitted to them (the rows' stage, from
    ``x``): how well the turns about the vertical of ``x`` let the pairs stand on their rows."""
    best = _fit(_Stage(old, pairs, x, ROW_PARAMS))[0]
    r = np.nan_to_num(_points(best, old, pairs)[2] / pairs.sigma_px, nan=_MISS)
    return float(np.sum(2.0 * LOSS_SIGMAS ** 2 * (np.sqrt(1.0 + (r / LOSS_SIGMAS) ** 2) - 1.0)))


def _pinned(cov: np.ndarray) -> int:
    """How many combinations of the turns about the vertical the tares pinned: those whose posterior sigma (in
    ``cov``, the tilts' covariance, rad^2) is under 0.99 of the prior's."""
    k = list(DEPTH_PARAMS)
    return int(np.sum(np.linalg.eigvalsh(cov[np.ix_(k, k)] / DRIFT_SIGMA_RAD ** 2) < 0.99))


def _record(rig: Rig, rms_px: float, frames: int, distances: tuple[float, ...]) -> Calibration:
    """The rig file's [calibration] record: the refit's reprojection RMS (both views alike), the images."""
    kinds = f"refit from {frames} frame(s)"
    if distances:
        kinds += ", tare(s) at " + ", ".join(f"{z:g}" for z in distances) + " mm"
    base = rig.calibration
    if base is not None and base.kinds:
        kinds += f" of a calibration from {base.images} {base.kinds}"
    return Calibration(rms_px, rms_px, rms_px, frames + len(distances), kinds)


def _read_pairs(check: HealthCheck, tare_images, rig: Rig, near_mm, far_mm, tolerance_px) -> _Pairs:
    """The judged tiles of the frames (their ``check`` through ``rig``) and of each tare as twin pairs."""
    def pairs_of(c, what):
        if c.tiles == 0 or not np.all(np.isfinite(c.fitted_px)):
            raise MeasurementError(f"cannot refit: {what}: {c.reason}")
        return judged_pairs_px(c, rig, near_mm, far_mm)
    left, right = pairs_of(check, "the frames")
    source = [np.full(len(left), -1)]
    for k, img in enumerate(tare_images):
        tl, tr = pairs_of(check_frames([img], rig, near_mm, far_mm, tolerance_px), f"tare {k + 1}")
        left, right = np.vstack([left, tl]), np.vstack([right, tr])
        source.append(np.full(len(tl), k))
    source = np.concatenate(source)
    ok = triangulate(left, right, rig, model="exact").valid
    sigma = math.sqrt(OVERLAP) * max(check.scatter_px, MIN_SCATTER_PX) / math.sqrt(2)
    return _Pairs(left[ok], right[ok], source[ok], sigma)


def _frames_only(pairs: _Pairs) -> _Pairs:
    """The frames' pairs of ``pairs`` (the tares' left out)."""
    keep = pairs.source < 0
    return _Pairs(pairs.left[keep], pairs.right[keep], pairs.source[keep], pairs.sigma_px)


def _rig(x: np.ndarray, old: Rig) -> Rig:
    """``old`` with the refitted tilts changed by ``x`` (len(REFIT_PARAMS),) rad."""
    values = rig_values(old)
    for p, dx in zip(REFIT_PARAMS, x, strict=True):
        values[p] += float(dx)
    return rig_from_values(values, old)


def _points(x, old: Rig, pairs: _Pairs):
    """(rig, points (n, 3) mm, reprojection residuals (n, 4) px, NaN where lost) for a trial change ``x``."""
    rig = _rig(x, old)
    tri = triangulate(pairs.left, pairs.right, rig, model="exact")
    res = np.full((len(pairs.left), 4), np.nan)
    ok = tri.valid
    pl, okl = project_points(tri.points_mm[ok], rig, "left")
    pr, okr = project_points(tri.points_mm[ok], rig, "right")
    r = np.hstack([pl - pairs.left[ok], pr - pairs.right[ok]])
    r[~(okl & okr)] = np.nan
    res[ok] = r
    return rig, tri.points_mm, res


@dataclass(frozen=True)
class _Stage:
    old: Rig
    pairs: _Pairs
    x_base: np.ndarray                  # (len(REFIT_PARAMS),) the change from ``old`` the stage starts at
    free: tuple[int, ...]               # indices into REFIT_PARAMS the stage fits
    distances: tuple[float, ...] = ()   # the depth's stage: each tare's distance (mm); the rows' stage: ()
    distance_sigma_mm: float = 0.0      # ... each known to this (1 sigma): its error is one more unknown

    @property
    def offsets(self) -> int:
        """How many unknowns follow the free tilts: each tare's distance error, when its distance has a sigma."""
        return len(self.distances) if self.distance_sigma_mm > 0 else 0


def _residuals(xs, stage: _Stage) -> np.ndarray:
    """The stage's residuals (in sigmas) for its free tilts and then its tares' distance errors (mm) ``xs``:
    every pair's reprojection (the rows' stage) or each tare pair's depth off its tare's plane (the depth's
    stage; the plane through the stated distance plus its error)."""
    x = stage.x_base.copy()
    x[list(stage.free)] = xs[:len(stage.free)]
    offsets = np.asarray(xs[len(stage.free):], dtype=float) if stage.offsets else np.zeros(len(stage.distances))
    rig, pts, res = _points(x, stage.old, stage.pairs)
    s = stage.pairs.sigma_px
    if not stage.distances:
        return np.nan_to_num(res / s, nan=_MISS).ravel()
    out = []
    for k, z in enumerate(stage.distances):
        at = np.flatnonzero(stage.pairs.source == k)
        seen = np.all(np.isfinite(res[at]), axis=1)
        off = np.full(len(at), _MISS)
        off[seen] = depth_residuals_px(pts[at[seen]], z + float(offsets[k]), rig) / s
        out.append(off)
    return np.concatenate(out)


def _jacobian(xs, stage: _Stage) -> np.ndarray:
    f0 = _residuals(xs, stage)
    J = np.empty((len(f0), len(xs)))
    for k in range(len(xs)):
        e = np.zeros_like(xs)
        e[k] = _STEP
        J[:, k] = (_residuals(xs + e, stage) - f0) / _STEP
    return J


def _fit(stage: _Stage):
    """One stage by truncated Gauss-Newton in units of the priors: only the combinations of its unknowns the
    stage's residuals pin (to under :data:`UNPINNED` of their prior's sigma: singular values of the Jacobian,
    in units of the residuals' and the priors' sigmas, over 1 / UNPINNED) are fitted, at the least change;
    the others keep their values. The unknowns: the free tilts (prior :data:`DRIFT_SIGMA_RAD`) and, on the
    depth's stage, each tare's distance error (prior ``stage.distance_sigma_mm``): a tare stated 0.4 mm off
    the calibration's O (whose place on the axis a card calibration knows no better: its depth there 0.1 %
    off at 400 mm) had turned the views' convergence by 6 of the sigmas stated while the fit took every
    distance as exact, and two such tares pin the depth's scale only as well as their distances do. The rows'
    residuals are weighed soft-L1 (:data:`LOSS_SIGMAS`, iteratively reweighted): a tile across a depth edge is
    no one point. Returns (the change from ``stage.old`` (len(REFIT_PARAMS),) rad, the free tilts' covariance
    (pinned combinations: Gauss-Newton, scaled by the residuals' chi^2 when over 1; the others: their priors;
    the distances' errors marginalised), iterations)."""
    free = list(stage.free)
    d = np.concatenate([np.full(len(free), DRIFT_SIGMA_RAD), np.full(stage.offsets, stage.distance_sigma_mm)])
    x, offsets = stage.x_base.copy(), np.zeros(stage.offsets)
    V, var, it = np.eye(len(d)), np.ones(len(d)), 0
    for it in range(1, ITERATIONS + 1):
        here = dataclasses.replace(stage, x_base=x)
        xs = np.concatenate([x[free], offsets])
        r = _residuals(xs, here)
        J = _jacobian(xs, here) * d
        w = np.ones(len(r)) if stage.distances else np.sqrt(1.0 / np.sqrt(1.0 + (r / LOSS_SIGMAS) ** 2))
        U, sv, Vt = np.linalg.svd(J * w[:, None], full_matrices=False)
        keep = sv >= 1.0 / UNPINNED
        step = -(Vt[keep].T @ ((U[:, keep].T @ (w * r)) / sv[keep]))
        x[free] += d[:len(free)] * step[:len(free)]
        offsets += d[len(free):] * step[len(free):]
        # a pair pins one number (its free point takes three of its four residuals); a tare's plane takes two
        data = len(r) - 2 * len(stage.distances) if stage.distances else len(r) // 4
        s2 = max(1.0, float(np.sum((w * r) ** 2)) / max(data - int(keep.sum()), 1))
        V, var = Vt.T, np.where(keep, s2 / np.maximum(sv, 1e-12) ** 2, 1.0)
        if np.max(np.abs(step)) < STEP_DONE:
            break
    n = len(free)
    return x, ((V * var) @ V.T * np.outer(d, d))[:n, :n], it


def _on_tare_planes(x, old: Rig, pairs: _Pairs, distances) -> _Pairs:
    """``pairs`` less the tares' points off their planes (through the rig of the change ``x``: tiles matched
    wrongly, something before the wall); MeasurementError when a tare is not flat (:func:`check_flat`)."""
    rig, pts, res = _points(x, old, pairs)
    noise = pairs.sigma_px / math.sqrt(OVERLAP) * math.sqrt(2)
    keep = np.ones(len(pairs.source), bool)
    for k in range(len(distances)):
        at = np.flatnonzero((pairs.source == k) & np.all(np.isfinite(res), axis=1))
        keep[at] = check_flat(pts[at], rig, noise, f"tare {k + 1}" if len(distances) > 1 else "the tare surface",
                              f", or it does not stand at the {distances[k]:g} mm stated (a rig refitted to a "
                              "wrong distance bends the surface)")
    return _Pairs(pairs.left[keep], pairs.right[keep], pairs.source[keep], pairs.sigma_px)


def _tares(pairs: _Pairs, old: Rig, new: Rig, distances) -> tuple[Tare, ...]:
    out = []
    for k, z in enumerate(distances):
        at = pairs.source == k
        before = triangulate(pairs.left[at], pairs.right[at], old, model="exact")
        after = triangulate(pairs.left[at], pairs.right[at], new, model="exact")
        ok = before.valid & after.valid
        out.append(tare_record(before.points_mm[ok], after.points_mm[ok], z, new))
    return tuple(out)


def _propagated_sigma(quantity, rig: Rig, cov: np.ndarray) -> np.ndarray:
    """The 1 sigma (n,) of ``quantity(rig)`` (an array (n,)) under the tilts' covariance ``cov``
    (len(REFIT_PARAMS),) x 2, rad^2: forward differences of :data:`_STEP` rad through :func:`_rig`."""
    q0 = np.asarray(quantity(rig), dtype=float)
    g = np.array([(np.asarray(quantity(_rig(step, rig))) - q0) / _STEP
                  for step in _STEP * np.eye(len(REFIT_PARAMS))]).T          # (n, params) per rad
    return np.sqrt(np.clip(np.einsum("ij,jk,ik->i", g, cov, g), 0.0, None))


def scale_sigma(rig: Rig, cov: np.ndarray) -> float:
    """The relative 1 sigma of the baseline |O1 O2| (the reconstruction's scale) under the tilts'
    covariance ``cov`` (len(REFIT_PARAMS),) x 2, rad^2 (finite differences of the virtual centres)."""
    return float(_propagated_sigma(lambda r: [virtual_baseline_mm(r)], rig, cov)[0]) / virtual_baseline_mm(rig)


def depth_sigma(rig: Rig, cov: np.ndarray, depths_mm) -> tuple[tuple[float, float], ...]:
    """((Z, relative 1 sigma), ...) of the depth of points on the axis at ``depths_mm`` (mm) under the tilts'
    covariance ``cov`` (len(REFIT_PARAMS),) x 2, rad^2: how far the depth a pair of twin pixels gives moves
    with what the refit left uncertain (finite differences of the exact triangulation of each point's twins,
    the pixels held). Without a tare the views' convergence stays at its prior: a knock within it moved a wall
    at 1000 mm by 1.8 % while the baseline's sigma (:func:`scale_sigma`) said 0.45 % (an adversarial trial)."""
    z = np.asarray(depths_mm, dtype=float)
    points = np.column_stack([np.zeros_like(z), np.zeros_like(z), z])
    left, _ = project_points(points, rig, "left")
    right, _ = project_points(points, rig, "right")
    sigma = _propagated_sigma(lambda r: triangulate(left, right, r, model="exact").points_mm[:, 2], rig, cov)
    return tuple((float(zz), float(sz / zz)) for zz, sz in zip(z, sigma, strict=True))


def unpinned_combinations(cov: np.ndarray) -> tuple[tuple[tuple[str, float], ...], ...]:
    """The combinations of the refitted tilts no frame could pin: in units of their priors, the directions
    along which the posterior's sigma is still over :data:`UNPINNED` of the prior's (the data barely narrowed
    them). Each as its largest components ((name in files, weight), ...), the weights those of a unit
    vector, the largest positive."""
    d = np.full(len(REFIT_PARAMS), DRIFT_SIGMA_RAD)
    lam, vec = np.linalg.eigh(cov / np.outer(d, d))
    out = []
    for k in np.flatnonzero(np.sqrt(np.clip(lam, 0, None)) > UNPINNED)[::-1]:
        v = vec[:, k] * np.sign(vec[np.argmax(np.abs(vec[:, k])), k])
        top = np.argsort(-np.abs(v))[:3]
        out.append(tuple((_file_name(REFIT_PARAMS[i]), round(float(v[i]), 2)) for i in top if abs(v[i]) >= 0.2))
    return tuple(out)


def combination_text(combo) -> str:
    """'+0.71 m1_tilt_a_deg -0.70 m3_tilt_a_deg' for a combination of :func:`unpinned_combinations`."""
    return " ".join(f"{w:+.2f} {name}" for name, w in combo)
