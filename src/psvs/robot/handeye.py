"""Hand-eye calibration: where the PSVS (frame C) sits on the flange, from views of a circle-grid target.

The robot shows the target to the PSVS from several flange poses. In each complex image the grid is found
in both views through the rig's epipolar geometry (:func:`psvs.targets.detect.detect_target`: the two
views may interleave, discs may touch), its disc centres are triangulated (exact model),
and the rigid transform target -> frame C is the least-squares fit of the grid's known layout to them
(Kabsch). With the flange poses from the arm's kinematics, AX = XB is solved for X = cam2flange by
Park & Martin's closed form [1] (OpenCV 4's ``calibrateHandEye`` with ``CALIB_HAND_EYE_PARK``; OpenCV 5's
Python wheels no longer ship that function, so psvs solves it itself and the tests compare the two where
OpenCV 4 is installed).

[1] F. C. Park, B. J. Martin, "Robot sensor calibration: solving AX = XB on the Euclidean group",
    IEEE Trans. Robotics and Automation 10(5), 1994.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from psvs.errors import MeasurementError
from psvs.measure.triangulate import epipolar_gap_px, triangulate
from psvs.optics.rig import Rig
from psvs.simulate.textures import CircleGrid
from psvs.targets.detect import detect_target
from psvs.targets.rim import EDGE_PX
from psvs.transforms import concat, invert_transform, transform_from, transform_points


def rigid_fit(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares rigid transform (4, 4) mapping src (N, 3) onto dst (N, 3) (Kabsch), and its RMS
    residual, mm."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    U, _, Vt = np.linalg.svd((src - cs).T @ (dst - cd))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    T = transform_from(R, cd - R @ cs)
    res = dst - transform_points(T, src)
    return T, float(np.sqrt(np.mean(np.sum(res ** 2, axis=1))))


@dataclass(frozen=True, eq=False)
class TargetFit:
    """The grid in one complex image under one labelling of its discs: target2cam (4, 4) mm, the rigid
    fit's RMS residual (mm), the detected disc centres in each view, (n, 2) px, and the discs triangulated
    (exact model), (n, 3) mm, row k the grid's k-th disc (:meth:`psvs.simulate.textures.CircleGrid.centres_mm`
    order), NaN where it was not read."""

    target2cam: np.ndarray
    rms_mm: float
    left_px: np.ndarray
    right_px: np.ndarray
    points_mm: np.ndarray


def target_candidates(grey: np.ndarray, rig: Rig, grid: CircleGrid) -> list[TargetFit]:
    """The four fits a symmetric grid gives equally well in one complex image (its discs labelled as they
    are, turned half about the grid's normal, or flipped over about either axis). The grid is found in
    both views and its discs triangulated (exact model). ValueError when the image does not show every disc
    of the grid in both views, told apart for certain."""
    left, right = grid_views(grey, rig, grid)
    seen = np.isfinite(left[:, 0])
    pts = np.full((len(left), 3), np.nan)
    pts[seen] = triangulate(left[seen], right[seen], rig, model="exact").points_mm
    if not np.all(np.isfinite(pts[seen])):
        raise ValueError("grid discs could not be triangulated")
    model = grid_points(grid)
    idx = np.arange(grid.rows * grid.cols).reshape(grid.rows, grid.cols)
    out = []
    for order in (idx, idx[::-1], idx[:, ::-1], idx[::-1, ::-1]):
        k = order.ravel()
        fit = seen[k]
        out.append(TargetFit(*rigid_fit(model[fit], pts[k][fit]), left[k], right[k], pts[k]))
    return out


def grid_views(grey: np.ndarray, rig: Rig, grid: CircleGrid) -> tuple[np.ndarray, np.ndarray]:
    """The discs of ``grid`` in both views of one complex image, (rows * cols, 2) px each, row k the grid's
    k-th disc; NaN where the disc was not found or cannot be trusted (two views' discs merged, out of the
    frame). ValueError (what to do) when under half the discs are read, or their ids are not certain."""
    det = detect_target(grey, grid, rig)
    n = grid.rows * grid.cols
    if not det.ids_certain:
        raise ValueError("the grid's discs cannot be told apart in this view: show the whole target, "
                         "not only part of it")
    good = det.reliable
    if good.sum() < max(n // 2, 6):
        raise ValueError(f"only {int(good.sum())} of the {grid.rows}x{grid.cols} grid's {n} discs read in both "
                         "views: show the whole target to the camera")
    left, right = np.full((n, 2), np.nan), np.full((n, 2), np.nan)
    left[det.ids[good]], right[det.ids[good]] = det.left[good], det.right[good]
    return left, right


def grid_points(grid: CircleGrid) -> np.ndarray:
    """The grid's disc centres in its own frame (z = 0), (rows * cols, 3) mm."""
    return np.column_stack([grid.centres_mm(), np.zeros(grid.rows * grid.cols)])


def labelled_as(candidates: list[TargetFit], expected: np.ndarray) -> TargetFit:
    """Of one image's four labellings (:func:`target_candidates`), the one whose rotation is nearest to
    ``expected`` (a rough target2cam (4, 4), e.g. from the nominal mounting)."""
    return min(candidates, key=lambda c: np.linalg.norm(c.target2cam[:3, :3] - expected[:3, :3]))


def rotation_angle_rad(R: np.ndarray) -> float:
    """The angle (rad) of the rotation matrix R (3, 3) about its axis."""
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


def consistent_labellings(candidates: list[list[TargetFit]], flange2base: list[np.ndarray]) -> list[TargetFit]:
    """One target2cam per view, labelled consistently without any pose guess: the first view's first
    labelling defines the target frame (X does not depend on it), and every other view takes the labelling
    whose motion relative to the first turns by the same angle as the flange's (A X = X B makes A and B
    similar: equal rotation angles). The wrong labellings differ by half turns."""
    F0 = flange2base[0]
    first = candidates[0][0]
    out = [first]
    for cands, F in zip(candidates[1:], flange2base[1:], strict=True):
        want = rotation_angle_rad(np.linalg.solve(F, F0)[:3, :3])
        out.append(min(cands, key=lambda c: abs(rotation_angle_rad(concat(invert_transform(first.target2cam),
                                                              c.target2cam)[:3, :3]) - want)))
    return out


#: mm: the flange pose accuracy assumed of the robot when none is stated (an industrial arm's absolute
#: accuracy, ISO 9283, is 0.1-1 mm uncalibrated): what the hand-eye fit's residual may hold beyond the
#: detector's noise (:func:`_check_fit`).
ROBOT_ACCURACY_MM = 0.5
#: mm: the worst flange pose accuracy a robot may be stated to have (a large arm uncalibrated holds a few mm):
#: beyond it any poses pass the residual test, and no mount comes of them (:func:`check_robot_accuracy`).
MAX_ROBOT_ACCURACY_MM = 10.0
#: The least a hand-eye calibration must pin the mount to (1-sigma, on each axis and in orientation): what a
#: mounting drawing and a ruler already give. A mount known no better than this is no calibration: the fit is
#: refused (:func:`check_mount_pinned`), not written (six views with a 10 mm robot accuracy and poses shifted one
#: row against their images wrote a mount 174 mm off at 1-sigma 94 mm, exit 0).
MAX_MOUNT_SIGMA_MM = 5.0
MAX_MOUNT_SIGMA_DEG = 2.0


def check_robot_accuracy(accuracy_mm: float, name: str = "robot_accuracy_mm") -> None:
    """ValueError naming ``name`` unless ``accuracy_mm`` is a flange pose accuracy in (0,
    :data:`MAX_ROBOT_ACCURACY_MM`] mm."""
    if not (math.isfinite(accuracy_mm) and 0 < accuracy_mm <= MAX_ROBOT_ACCURACY_MM):
        raise ValueError(f"{name} must be a robot's flange pose accuracy in (0, {MAX_ROBOT_ACCURACY_MM:g}] mm, got "
                         f"{accuracy_mm:g}")


@dataclass(frozen=True, eq=False)
class HandEyeResult:
    """cam2flange (4, 4) mm; per-view target fit RMS (mm); the spread of the target's base pose over
    the views (translation mm, rotation rad): the calibration's consistency; and the reprojection RMS of
    the grid's discs in both views at the solution (px; None when not known, e.g. an older file); the
    views left out as unreadable, (index, reason) each (a session's fact, not kept in handeye.toml); and the
    mount's 1-sigma uncertainty from its inputs' noise, position (mm, RMS over the axes) and orientation
    (rad) (:mod:`psvs.robot.handeye_noise`; None when not known); and the geometry of the rig it was
    calibrated through (:func:`psvs.io.rig_digest`; None when not known: a session's result, an older file)."""

    cam2flange: np.ndarray
    target_rms_mm: np.ndarray
    spread_mm: float
    spread_rad: float
    reprojection_rms_px: float | None = None
    skipped: tuple = ()
    mount_sigma_mm: float | None = None
    mount_sigma_rad: float | None = None
    rig_sha256: str | None = None


def _check_fit(rms_px: float, noise, robot_accuracy_mm: float) -> None:
    """MeasurementError when the joint fit's reprojection RMS (px) is beyond what its inputs' noise gives at
    its solution 99 % of the time (``noise``: :class:`psvs.robot.handeye_noise.ResidualNoise`): the
    detector's precision (:data:`psvs.targets.rim.EDGE_PX` on each coordinate) and the robot's stated
    accuracy on every view's pose, less what the fit absorbs. Not the grid's own fit in each view: a card
    printed at another scale, or views of another rig, fit their own views badly too (issue 41's trial: the
    mount 15-20 mm off at 3.3-5.3 px). Poses that belong to other images (shifted by one row) or in other
    units leave residuals of tens of px; poses six times noisier than stated passed a limit of three times
    the noise's RMS (the third trial: a mount 10 mm off)."""
    if not (math.isfinite(rms_px) and rms_px <= noise.limit_px):
        raise MeasurementError(
            f"the hand-eye calibration does not fit its data: RMS residual {rms_px:.3g} px is "
            f"{rms_px / noise.expected_px:.1f} times the {noise.expected_px:.3g} px that the detector's precision "
            f"({EDGE_PX:g} px) with a {robot_accuracy_mm:g} mm robot accuracy explains (limit {noise.limit_px:.3g} "
            "px, exceeded by that noise 1 % of the time): the poses are not the images' poses, are noisier than "
            "--robot-accuracy-mm says, or the views disagree with the rig")


def check_mount_pinned(sigma_mm: float, sigma_rad: float, source: str) -> None:
    """MeasurementError when a mount's 1-sigma (position mm on each axis, orientation rad) exceeds
    :data:`MAX_MOUNT_SIGMA_MM` or :data:`MAX_MOUNT_SIGMA_DEG`: its views did not pin it better than its drawing
    does. ``source`` says where the figure comes from, e.g. "from ... over 6 views"."""
    mm, deg = sigma_mm, math.degrees(sigma_rad)
    if not (math.isfinite(mm) and math.isfinite(deg) and mm <= MAX_MOUNT_SIGMA_MM and deg <= MAX_MOUNT_SIGMA_DEG):
        raise MeasurementError(
            f"the views cannot pin the mount: its 1-sigma {source} is {mm:.3g} mm on each axis and {deg:.3g} deg, "
            f"beyond the {MAX_MOUNT_SIGMA_MM:g} mm and {MAX_MOUNT_SIGMA_DEG:g} deg a mounting drawing gives: more "
            "views over wider turns of the flange, or a more accurate robot")


#: px: a disc's twin lies on its epipolar curve through the rig the views were taken through within two centres'
#: precision (:data:`psvs.targets.rim.EDGE_PX` each), times 2 (the circle pattern's margin)
TWIN_GAP_PX = 4 * EDGE_PX
#: How far the card's size in the views may differ from its target file's (a print's scale and a calibrated
#: baseline each hold about 0.5 %): beyond, the mount would be off by as large a share of the target's distance.
SCALE_TOL = 0.01


def check_views(fits: list, rig: Rig, grid: CircleGrid) -> None:
    """MeasurementError when the views cannot be the card of ``grid`` seen through ``rig``: the discs' twins
    stand off their epipolar curves (median over the views beyond :data:`TWIN_GAP_PX`: views of another rig, or
    a rig moved since its calibration), or the triangulated grid is larger or smaller than the target file
    says (the mean of the views' scales, the RMS spread of the discs about their centroid over the file's,
    beyond :data:`SCALE_TOL` and 3 standard errors over the views: a card printed at another scale). Issue 41's
    trial: both gave mounts 15-20 mm off, accepted."""
    def spread(p: np.ndarray) -> float:     # RMS distance of points (n, 3) from their centroid
        return float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))

    gaps, scales = [], []
    model = grid_points(grid)
    for f in fits:
        ok = np.isfinite(f.points_mm[:, 0])
        gaps.append(float(np.median(epipolar_gap_px(f.left_px[ok], f.right_px[ok], rig))))
        scales.append(spread(f.points_mm[ok]) / spread(model[ok]))
    gap = float(np.median(gaps))                 # NaN (a twin off the rig's field) is refused too
    if not gap <= TWIN_GAP_PX:
        raise MeasurementError(f"the discs' twins stand {gap:.1f} px off their epipolar curves through this rig "
                               f"(the median over {len(fits)} views; the detector places them within {TWIN_GAP_PX:g} "
                               "px): views of another rig, or a rig that has moved since its calibration")
    scale, se = float(np.mean(scales)), float(np.std(scales, ddof=1) / np.sqrt(len(scales)))
    if not abs(scale - 1.0) <= max(SCALE_TOL, 3 * se):      # NaN (a disc not triangulated) is refused too
        raise MeasurementError(f"the card in the views is {scale:.4f} times the size its target file says "
                               f"(+-{se:.4f} over {len(fits)} views; a print's scale and a calibrated baseline hold "
                               f"{SCALE_TOL:.0%}): a card printed at another scale, or the rig of another build; "
                               "the mount would be off by as large a share of the target's distance")


def calibrate_hand_eye(flange2base: list[np.ndarray], target2cam: list[np.ndarray]) -> np.ndarray:
    """X = cam2flange (4, 4, mm) from >= 3 pairs of flange2base and target2cam (4, 4, mm) poses.

    The target is fixed in the base: F_i X T_i is the same for every view i, so for every pair of views
    A X = X B with A = F_j^-1 F_i (flange motion) and B = T_j T_i^-1 (target motion seen by the camera).
    Park & Martin: the rotation vectors obey log(R_A) = R_X log(R_B), solved for R_X in the least-squares
    sense over all pairs (orthogonal Procrustes); then (R_A - I) t_X = R_X t_B - t_A is linear in t_X.
    Pairs whose motion turns by less than 1e-6 rad carry no rotation information and are left out of the
    rotation step. With all motions about one axis, X's rotation about it is unobservable: ValueError.
    """
    if len(flange2base) != len(target2cam) or len(flange2base) < 3:
        raise ValueError(f"hand-eye calibration needs >= 3 paired views, got {len(flange2base)} and {len(target2cam)}")
    F = [np.asarray(T, dtype=np.float64) for T in flange2base]
    C = [np.asarray(T, dtype=np.float64) for T in target2cam]
    A, B = [], []
    for i in range(len(F)):
        for j in range(i + 1, len(F)):
            A.append(np.linalg.solve(F[j], F[i]))
            B.append(C[j] @ invert_transform(C[i]))
    alpha = Rotation.from_matrix(np.array([a[:3, :3] for a in A])).as_rotvec()
    beta = Rotation.from_matrix(np.array([b[:3, :3] for b in B])).as_rotvec()
    turns = np.linalg.norm(alpha, axis=1) > 1e-6
    axes = alpha[turns] / np.linalg.norm(alpha[turns], axis=1, keepdims=True)
    spread = np.linalg.svd(axes, compute_uv=False) if len(axes) else np.zeros(1)
    if len(spread) < 2 or spread[1] < 1e-3 * spread[0]:
        raise ValueError("hand-eye calibration needs flange poses that turn about at least two axes")
    R, _ = Rotation.align_vectors(alpha[turns], beta[turns])
    R = R.as_matrix()
    lhs = np.concatenate([a[:3, :3] - np.eye(3) for a in A])
    rhs = np.concatenate([R @ b[:3, 3] - a[:3, 3] for a, b in zip(A, B, strict=True)])
    return transform_from(R, np.linalg.lstsq(lhs, rhs, rcond=None)[0])


def calibrate_from_views(images: list[np.ndarray], flange2base: list[np.ndarray], rig: Rig, grid: CircleGrid,
                         nominal_cam2flange: np.ndarray | None = None,
                         target2base_guess: np.ndarray | None = None,
                         robot_accuracy_mm: float = ROBOT_ACCURACY_MM) -> HandEyeResult:
    """Hand-eye calibration from complex images of the grid taken at the given flange poses.

    Each view's grid is found and triangulated (:func:`target_candidates`); Park & Martin's closed form
    (:func:`calibrate_hand_eye`) on those poses starts a least-squares refinement of cam2flange and the
    target's pose in the base over the discs' reprojection error in both views through the exact optics
    (:func:`psvs.robot.handeye_refine.refine_hand_eye`): the closed form weighs every pose alike and
    carries each view's rotation noise into the translation, the refinement weighs each disc by what the
    images see of it.

    ``nominal_cam2flange`` (the mounting drawing) and ``target2base_guess`` (roughly where the target
    lies) pick the grid's labelling in each view; without them the labellings are made consistent by the
    views' motions (:func:`consistent_labellings`). The result comes from the images either way. A view
    whose grid cannot be read (:func:`grid_views`) is left out and listed in ``skipped``; ValueError when
    fewer than 3 views are read."""
    from psvs.robot.handeye_refine import fit_noise, refine_hand_eye
    from psvs.robot.handeye_turns import check_turns, turn_agreement
    check_robot_accuracy(robot_accuracy_mm)
    if len(images) != len(flange2base):
        raise ValueError(f"{len(images)} images but {len(flange2base)} flange poses")
    cands, used, skipped = [], [], []
    for k, img in enumerate(images):
        try:
            cands.append(target_candidates(img, rig, grid))
            used.append(k)
        except ValueError as e:
            skipped.append((k, str(e)))
    if len(used) < 3:
        raise ValueError(f"hand-eye calibration needs >= 3 readable views, {len(used)} of {len(images)} read"
                         + "".join(f"; view {k}: {why}" for k, why in skipped[:3]))
    flange2base = [flange2base[k] for k in used]
    if nominal_cam2flange is not None and target2base_guess is not None:
        fits = [labelled_as(c, invert_transform(F @ nominal_cam2flange) @ target2base_guess)
                for c, F in zip(cands, flange2base, strict=True)]
    else:
        fits = consistent_labellings(cands, flange2base)
    check_views(fits, rig, grid)
    t2c = [f.target2cam for f in fits]
    X0 = calibrate_hand_eye(flange2base, t2c)
    X, T, rms_px = refine_hand_eye(flange2base, fits, grid_points(grid), rig, X0)
    noise = fit_noise(flange2base, fits, grid_points(grid), rig, X, T, EDGE_PX, robot_accuracy_mm)
    _check_fit(rms_px, noise, robot_accuracy_mm)
    check_mount_pinned(noise.mount_sigma_mm, noise.mount_sigma_rad, f"from the detector's precision and a "
                       f"{robot_accuracy_mm:g} mm robot accuracy over {len(used)} views")
    check_turns(turn_agreement(fits, flange2base, X, grid_points(grid), robot_accuracy_mm), robot_accuracy_mm)
    targets = [concat(T, X, F) for F, T in zip(flange2base, t2c, strict=True)]
    pos = np.array([T[:3, 3] for T in targets])
    ang = [rotation_angle_rad(targets[0][:3, :3].T @ T[:3, :3]) for T in targets]
    return HandEyeResult(X, np.array([f.rms_mm for f in fits]),
                         float(np.max(np.linalg.norm(pos - pos.mean(axis=0), axis=1))), float(np.max(ang)), rms_px,
                         tuple(skipped), noise.mount_sigma_mm, noise.mount_sigma_rad)
