"""Calibrate a build from a folder of complex images: hand-held grid views, a robot sweep, or both.

The folder holds images (any file :func:`psvs.io.images.read_grey` reads: PNG, JPEG, BMP, TIFF, PNM; grey
or colour) and ``target.toml`` (the hand-held card, :mod:`psvs.targets.target_file`)
and/or ``sweep.csv`` (the paper's robot sweep, :mod:`psvs.calibrate.sweep`). Images listed in ``sweep.csv``
are sweep images; every other image is a view of the card. Each image is detected on its own; one that
cannot be used is skipped with its reason (no grid found, too few discs on an even ground, or -- after a
first adjustment -- a target that fits no pose), and the bundle adjustment
(:func:`psvs.calibrate.bundle.bundle_adjust`) runs on the rest. A result no build of the start design can be
(a mirror turned degrees, a lens no lens is: :func:`psvs.evidence.check_build`) is refused
(``MeasurementError``): the folder holds another rig's views, or several rigs'. A folder that repeats a view is refused
before any work (``ValueError`` naming the duplicates): ``sweep.csv`` listing one image twice or one robot
position for two images, or two byte-identical images (a copy under another name). A repeat adds no
evidence, yet the adjustment would weigh it as new and count it as an image used.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from psvs._threads import one_blas_thread
from psvs.calibrate.bundle import PLAIN_SCALE_PX, BundleResult, GridView, bundle_adjust
from psvs.calibrate.misfit import check_misfit
from psvs.calibrate.pinned import check_scale_pinned
from psvs.calibrate.sweep import COUNT, detect_sweep, pattern_layout, read_sweep, sweep_views
from psvs.errors import MeasurementError
from psvs.evidence import check_build
from psvs.io.images import IMAGE_SUFFIXES, first_repeat, read_grey
from psvs.optics.mirrors import virtual_baseline_mm
from psvs.optics.rig import Calibration, Rig
from psvs.targets.detect import detect_target
from psvs.targets.target_file import load_target
from psvs.targets.target_points import Target, TargetDetection, target_points_mm

MIN_GRID_POINTS = 6        # fewer trusted points than this (x 2 views: 24 residuals, 6 pose unknowns): skipped
MAX_IMAGE_RMS_PX = 1.0     # an image whose points miss their fitted pose by more: skipped, refitted


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """The bundle adjustment's result, with the images used (name -> 'grid' or 'sweep'), the images
    skipped (name -> reason), and the effective baseline |O1 O2| of the calibrated rig (mm, 1-sigma)."""

    bundle: BundleResult
    used: dict
    skipped: dict = field(default_factory=dict)
    baseline_mm: float = float("nan")
    baseline_sigma_mm: float = float("nan")

    @property
    def rig(self) -> Rig:
        return self.bundle.rig

    @property
    def kinds(self) -> str:
        """The images used, counted by kind (e.g. "12 grid")."""
        kinds = sorted(set(self.used.values()))
        return ", ".join(f"{sum(v == k for v in self.used.values())} {k}" for k in kinds)

    def recorded_rig(self) -> Rig:
        """The calibrated rig with the record of the calibration that made it (its RMS per view, the images),
        as its rig file keeps it."""
        b = self.bundle
        return dataclasses.replace(b.rig, calibration=Calibration(b.rms_px, b.rms_by_view["left"],
                                                                   b.rms_by_view["right"], len(self.used),
                                                                   self.kinds))


def grid_view(name: str, grey: np.ndarray, target: Target, rig: Rig) -> GridView:
    """The trusted points of one card view (both images of each point located without bias), found
    through the nominal ``rig`` (:func:`psvs.targets.detect.detect_target`)."""
    return card_view(name, grey, target, rig)[0]


def card_view(name: str, grey: np.ndarray, target: Target, rig: Rig) -> tuple[GridView, TargetDetection]:
    """:func:`grid_view` and the detection it came from."""
    det = detect_target(grey, target, rig)
    if not det.ids_certain:      # a shifted labelling in one view's part would pull every view's fit
        raise ValueError(f"{len(det.ids)} points found, but which of the card's they are is not certain (part of "
                         "a symmetric grid fits them at several places): show the whole card, or turn it so that "
                         "its two copies overlap less")
    keep = det.reliable
    if keep.sum() < MIN_GRID_POINTS:
        raise ValueError(f"only {int(keep.sum())} of the {len(keep)} points found are located without bias in both "
                         f"views (a disc touching another, or another view's card edge across it); need "
                         f"{MIN_GRID_POINTS}: turn the card a little so that its two copies overlap less")
    return GridView(name, det.object_mm(target)[keep], det.left[keep], det.right[keep]), det


@one_blas_thread()
def calibrate_folder(folder, start: Rig) -> CalibrationResult:
    """Detect, adjust, drop images that fit no pose and adjust again (see the module docstring), on one BLAS
    thread: the result does not depend on the core count (:func:`psvs._threads.one_blas_thread`)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"calibration folder not found: {folder}")
    has_target, has_sweep = (folder / "target.toml").is_file(), (folder / "sweep.csv").is_file()
    if not has_target and not has_sweep:
        raise ValueError(f"{folder} holds neither target.toml (hand-held card views) nor sweep.csv (robot sweep)")
    skipped: dict[str, str] = {}
    sweeps = []
    items = read_sweep(folder) if has_sweep else []
    sweep_names = {p.name for p, _ in items}
    others = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.name not in sweep_names)
    check_distinct_images([p for p, _ in items] + (others if has_target else []))
    if has_sweep:
        found, bad = detect_sweep(items, COUNT, expect_size=start.camera.image_size_px, start=start)
        skipped.update(bad)
        sweeps = sweep_views(found)
    grids = []
    if has_target:
        grid = load_target(folder / "target.toml")
        most = 0
        for path in others:
            try:
                view, det = card_view(path.name, read_grey(path, expect_size=start.camera.image_size_px), grid, start)
            except ValueError as exc:
                skipped[path.name] = str(exc)
                continue
            grids.append(view)
            most = max(most, len(det.ids))
        _whole_target_seen(grids, most, grid)
    else:
        skipped.update({p.name: "not in sweep.csv, and no target.toml describes a card" for p in others})
    check_distinct_poses(grids)
    _enough(grids, sweeps, skipped)
    local = pattern_layout(COUNT) if sweeps else None
    res = bundle_adjust(grids, sweeps, start, sweep_local_mm=local)
    bad = {n: r for n, r in res.rms_by_image.items() if r > MAX_IMAGE_RMS_PX}
    if bad:
        res, bad = _from_plain_fit(grids, sweeps, start, local, res, bad)
    if bad:
        for name, rms in bad.items():
            skipped[name] = f"the target fits no pose (reprojection RMS {rms:.2f} px after adjustment)"
        kept_g, kept_s = [g for g in grids if g.name not in bad], [s for s in sweeps if s.name not in bad]
        _enough(kept_g, kept_s, skipped, fitted=True)
        res = bundle_adjust(kept_g, kept_s, start, sweep_local_mm=local if kept_s else None)
        # a start far from the build can leave good views unexplained (the first adjustment settles with
        # them as outliers): all of them again, from where the rest put the rig; those that fit now are kept
        again = bundle_adjust(grids, sweeps, start, sweep_local_mm=local, init=res.rig)
        still = {n for n, r in again.rms_by_image.items() if r > MAX_IMAGE_RMS_PX}
        if len(still) < len(bad):
            for name in set(bad) - still:
                del skipped[name]
            for name in still:
                skipped[name] = (f"the target fits no pose (reprojection RMS {again.rms_by_image[name]:.2f} px "
                                 "after adjustment)")
            if still:
                grids, sweeps = [g for g in grids if g.name not in still], [s for s in sweeps if s.name not in still]
                _enough(grids, sweeps, skipped, fitted=True)
                again = bundle_adjust(grids, sweeps, start, sweep_local_mm=local if sweeps else None, init=res.rig)
            res = again
        else:
            grids, sweeps = kept_g, kept_s
    used = {**{g.name: "grid" for g in grids}, **{s.name: "sweep" for s in sweeps}}
    # docs/right-or-refuse.md; the design's baseline checks a scale that rests on the card's print alone
    what = f"calibrating from {len(used)} image(s) of {folder}"
    check_build(res.rig, start, what, baseline=not sweeps)      # the more telling, where it applies
    check_misfit(res, grids, what)
    if not sweeps:                                              # a sweep's known steps pin the scale
        check_scale_pinned(res, what)
    b, sb = effective_baseline(res)
    return CalibrationResult(res, used, skipped, b, sb)


def _from_plain_fit(grids, sweeps, start: Rig, local, res, bad: dict) -> tuple:
    """(the adjustment, its views that fit no pose) of ``grids`` and ``sweeps`` started from a plain
    least-squares fit, when that leaves fewer views unexplained than ``res`` (whose ``bad`` views fit no pose),
    else ``res`` and ``bad``. From the design, a build's twins stand some px off, beyond the soft-L1 loss's
    scale: the robust fit then weighs every view as an outlier alike and can settle explaining a few of them
    (an adversarial trial: 18 views captured from a hand-held video of the misaligned build, started from
    `clear`, 16 left at 0.7-2.7 px and the folder refused; the plain fit, where every residual pulls, reached
    the build, and the robust fit from it explains all 18 at 0.065 px)."""
    plain = bundle_adjust(grids, sweeps, start, sweep_local_mm=local if sweeps else None,
                          loss_scale_px=PLAIN_SCALE_PX)
    again = bundle_adjust(grids, sweeps, start, sweep_local_mm=local if sweeps else None, init=plain.rig)
    left = {n: r for n, r in again.rms_by_image.items() if r > MAX_IMAGE_RMS_PX}
    return (again, left) if len(left) < len(bad) else (res, bad)


#: px RMS: two card views whose common points lie closer than this in both views show one pose (a dot's centre
#: moves by a few hundredths of a pixel between two photographs of it; a hand-held card by many pixels).
SAME_POSE_PX = 0.5


def check_distinct_poses(grids: list[GridView]) -> None:
    """ValueError naming two card views that show the card in one pose (their common points within
    :data:`SAME_POSE_PX` RMS in both views): a second photograph of a pose adds no view, yet the bundle
    adjustment would weigh it as one (an adversarial trial's 12 re-saved copies of one view gave a focal
    length 9 sigma off)."""
    keyed = [{tuple(np.round(o, 6)): k for k, o in enumerate(g.object_mm)} for g in grids]
    for i, a in enumerate(grids):
        for j in range(i):
            common = [(k, keyed[j][key]) for key, k in keyed[i].items() if key in keyed[j]]
            if len(common) < MIN_GRID_POINTS:
                continue
            ka, kb = (np.array(c) for c in zip(*common, strict=True))
            b = grids[j]
            d = np.hstack([a.left[ka] - b.left[kb], a.right[ka] - b.right[kb]])
            rms = float(np.sqrt(np.mean(np.sum(d.reshape(len(ka), -1, 2) ** 2, axis=2))))
            if rms < SAME_POSE_PX:
                raise ValueError(f"{b.name} and {a.name} show the card in one pose (its points {rms:.2f} px apart "
                                 "RMS): each view must be its own pose, the card moved between them")


def check_distinct_images(paths: list[Path]) -> None:
    """ValueError naming two images of the folder that are one photograph: byte-identical files (a copy
    under another name, :func:`psvs.io.images.first_repeat`). A copy adds no view, yet the bundle adjustment
    would weigh it as new evidence (and report one image more than the folder holds views)."""
    repeat = first_repeat(paths)
    if repeat is not None:
        a, b = (Path(paths[k]).name for k in repeat)
        raise ValueError(f"{a} and {b} are the same image (byte-identical files): each view must be its own photograph")


def _whole_target_seen(grids: list, most: int, target: Target) -> None:
    """ValueError when card views were read but none shows the whole target: a target read only in part in
    every view is likely not the one target.toml describes (a 4x6 card described as 5x6 reads as part of
    it in every view)."""
    n = len(target_points_mm(target))
    if grids and most < n:
        raise ValueError(f"no card view shows the whole target of target.toml ({n} points; at most {most} found in "
                         "a view): check target.toml's size against the printed card, or show the whole card")


def _enough(grids, sweeps, skipped, fitted: bool = False) -> None:
    """An error when fewer than 3 images are left: ValueError (bad input: exit 2) when the folder's images
    could not be read as views; :class:`~psvs.errors.MeasurementError` (exit 1) when ``fitted``, the views read
    but the adjustment found too few of them fitting one rig (the data cannot give a calibration)."""
    n = len(grids) + len(sweeps)
    if n < 3:
        shown = sorted(skipped.items())[:3]
        why = "; ".join(f"{k}: {v}" for k, v in shown)
        more = f" and {len(skipped) - len(shown)} more" if len(skipped) > len(shown) else ""
        error = MeasurementError if fitted else ValueError
        raise error(f"calibration needs at least 3 usable images, got {n}"
                    + (f" (skipped {len(skipped)} of {n + len(skipped)}: {why}{more})" if why else ""))


def effective_baseline(res: BundleResult) -> tuple[float, float]:
    """|O1 O2| of the calibrated rig (mm) and its 1-sigma (first-order propagation of the rig parameters'
    covariance)."""
    from psvs.calibrate.bundle import RIG_PARAMS, rig_from_vector, rig_vector

    x = rig_vector(res.rig)
    b0 = virtual_baseline_mm(res.rig)
    grad = np.zeros(len(RIG_PARAMS))
    for k in range(len(RIG_PARAMS)):
        dx = np.zeros(len(x))
        dx[k] = 1e-6
        grad[k] = (virtual_baseline_mm(rig_from_vector(x + dx, res.rig)) - b0) / 1e-6
    return b0, float(np.sqrt(max(grad @ res.covariance @ grad, 0.0)))
