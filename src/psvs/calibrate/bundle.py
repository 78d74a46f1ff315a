"""Bundle adjustment of a real build over the exact optics: the lens, the plate, the mirrors' pose errors
and every target pose, from hand-held grid views and/or the paper's robot sweep.

Unknowns (docs/calibration.md, "What is calibrated"):
- the lens: f, the principal point (cx, cy) and OpenCV's (k1, k2, p1, p2, k3);
- the M1 plate's thickness d and the baseline b;
- each mirror's two tilts (about +Y, about its horizontal in-plane axis) and M3's shift along its normal.
Held at the start rig's values because images cannot tell them apart from the others (docs/optics.md,
"What images can see"): the shifts of M1 and M2 (a periscope moved along its normal as a whole changes no
ray: M1 with M4, M2 with M3), M4's shift (with b free, b and the two far-mirror shifts have one degree of
freedom too many) and the box rotation (any turn of the box about O is a set of mirror tilts and shifts);
- per grid image: the target's pose (rotation vector, translation, frame C);
- with a robot sweep: the pattern's pose on the robot (ry, rz, x0, y0) and the robot's Z offset.
Two more combinations of the tilts move the whole reconstruction rigidly without changing any image (a
gauge). Every rig parameter therefore has a weak prior at the start rig's value (``PRIOR_SIGMA``), which
fixes those combinations at their nominal values and holds whatever a data set cannot see (e.g. the lens
terms from a sweep alone); the result says which parameters the data did not pin down.

Residuals: every detected disc or circle centre in both views minus the exact projection
(:func:`psvs.optics.project.project_points`) of its target point, px, with a soft-L1 loss (scale 0.5 px);
the priors are residuals (value - start) / sigma scaled to the detections' noise. Solved by scipy's
least_squares (trust-region reflective) with a finite-difference Jacobian (:meth:`BundleProblem.jacobian`: the
lens's columns without tracing a ray, the poses' through the projection's derivative by the point). Standard
deviations come from the Gauss-Newton covariance at the solution (:func:`covariance`, its columns scaled), scaled
by the residuals' variance.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from psvs._threads import one_blas_thread
from psvs.optics.mirrors import direction_map, virtual_centre
from psvs.optics.project import project_from
from psvs.optics.rig import MIRROR_NAMES, MirrorError, Rig
from psvs.optics.trace import pixels_from_camera_dirs
from psvs.transforms import transform_from_rotvec

#: Calibrated rig parameters, in the vector's order; tilts in rad. ``pixel_aspect``: the pixel's height over its
#: width (pitch_y / pitch_x; the width stays the start rig's, f carries the scale), OpenCV's fx / fy: a frame
#: grabber's or a resized frame's pixels are not square, and calibrated as square, 0.5 % taller gave 3-D points
#: 1.3 mm off (mean, after the rigid motion) at a reprojection RMS of 0.04 px (tests/calibrate/test_aspect.py).
RIG_PARAMS = ("focal_length_mm", "cx_px", "cy_px", "pixel_aspect", "k1", "k2", "p1", "p2", "k3",
              "plate_thickness_mm", "baseline_mm", "m1_tilt_a_rad", "m1_tilt_b_rad", "m2_tilt_a_rad", "m2_tilt_b_rad",
              "m3_tilt_a_rad", "m3_tilt_b_rad", "m4_tilt_a_rad", "m4_tilt_b_rad", "m1_shift_mm", "m2_shift_mm",
              "m3_shift_mm", "m4_shift_mm", "box_x_rad", "box_y_rad", "box_z_rad")
#: Prior standard deviations about the start rig (the nominal design): wide for the lens, where the data
#: decide; a build's tolerances for the mirrors (what a careful builder achieves: tenths of a degree,
#: tenths of a millimetre), which decide only what no image can see.
PRIOR_SIGMA = {"focal_length_mm": 2.0, "cx_px": 40.0, "cy_px": 40.0, "pixel_aspect": 0.05, "k1": 0.5, "k2": 0.5,
               "p1": 0.02, "p2": 0.02, "k3": 0.5, "plate_thickness_mm": 3.0, "baseline_mm": 20.0,
               **{f"m{k}_tilt_{a}_rad": np.radians(0.3) for k in range(1, 5) for a in "ab"},
               **{f"m{k}_shift_mm": 0.5 for k in range(1, 5)}, **{f"box_{a}_rad": np.radians(0.3) for a in "xyz"}}
SWEEP_PARAMS = ("offset_mm", "ry_rad", "rz_rad", "x0_mm", "y0_mm")
NOISE_PX = 0.05          # detection noise the priors are weighed against
#: The pixel's aspect is fitted where the views show it beyond chance, and otherwise held at the start rig's
#: (free with few views, it took the focal length's evidence along: 4 tilted card views of a square-pixel build
#: calibrated 1.3 mm off held, 6.6 mm free): a score test at the fit that holds it
#: (:func:`aspect_score`) against chi-square's 99.9 % point for 1 degree of freedom.
ASPECT = "pixel_aspect"
ASPECT_SCORE_LIMIT = 10.83
#: What a robot sweep alone (one row of circles moved along Z: no length across the rows) cannot see: held at
#: the start rig's values.
SWEEP_HOLDS = ("pixel_aspect", "k2", "p1", "p2", "k3")
#: ... and, first, the design's mirrors: a sweep frees them only when the design cannot explain its images.
DESIGN_HOLDS = SWEEP_HOLDS + tuple(p for p in RIG_PARAMS if p.startswith(("m1_", "m2_", "m3_", "m4_", "box_")))
DESIGN_FITS_PX = 3 * NOISE_PX
LOSS_SCALE_PX = 0.5      # soft-L1: residuals beyond this are treated as outliers
#: A loss scale beyond any residual of a build seen through its design (its mirrors put the twins some px off):
#: the soft-L1 fit is then plain least squares, whose every residual pulls (:func:`bundle_adjust`).
PLAIN_SCALE_PX = 50.0
_MISS_PX = 100.0         # residual of a point the optics cannot reach
DIFF_STEP = {"focal_length_mm": 1e-5, "cx_px": 1e-3, "cy_px": 1e-3, "pixel_aspect": 1e-7, "k1": 1e-6, "k2": 1e-6,
             "p1": 1e-7, "p2": 1e-7, "k3": 1e-6, "plate_thickness_mm": 1e-4, "baseline_mm": 1e-4,
             **{f"m{k}_shift_mm": 1e-4 for k in range(1, 5)}, **{f"box_{a}_rad": 1e-7 for a in "xyz"},
             **{f"m{k}_tilt_{a}_rad": 1e-7 for k in range(1, 5) for a in "ab"},
             "offset_mm": 1e-4, "ry_rad": 1e-7, "rz_rad": 1e-7, "x0_mm": 1e-4, "y0_mm": 1e-4}
POSE_STEP = (1e-7, 1e-7, 1e-7, 1e-4, 1e-4, 1e-4)
_POINT_STEP_MM = 1e-4
#: The lens's parameters: they change no ray through the mirrors, only the pixel a camera ray lands on.
LENS_PARAMS = ("focal_length_mm", "cx_px", "cy_px", "pixel_aspect", "k1", "k2", "p1", "p2", "k3")


@dataclass(frozen=True, eq=False)
class GridView:
    """One hand-held view of a planar target: ``object_mm`` (n, 3) in the target's frame (z = 0) and the
    detected centres ``left``, ``right`` (n, 2) px, row k of each the same target point."""

    name: str
    object_mm: np.ndarray
    left: np.ndarray
    right: np.ndarray


@dataclass(frozen=True, eq=False)
class SweepView:
    """One image of the robot sweep: the robot's Z reading (mm) and the pattern's centres in both views."""

    name: str
    position_mm: float
    left: np.ndarray
    right: np.ndarray


@dataclass(frozen=True, eq=False)
class BundleResult:
    """The calibrated rig, every parameter's value and 1-sigma (tilts in rad), the parameters the data did
    not pin down (their posterior sigma is over half the prior's), reprojection RMS overall / per view /
    per image (px), the residuals (u, v) and detections of each image's points per view, the target
    poses (4x4, target -> frame C) of the grid images, the solver's verdict, the sweep's parameters and
    the rig parameters' covariance."""

    rig: Rig
    values: dict
    sigma: dict
    held_by_prior: tuple
    rms_px: float
    rms_by_view: dict
    rms_by_image: dict
    residuals: dict
    observed: dict
    poses: dict
    success: bool
    message: str
    sweep: dict = field(default_factory=dict)
    covariance: np.ndarray | None = None   # (len(RIG_PARAMS),) * 2, of the rig parameters
    aspect_score: float | None = None      # the pixel's aspect held where this test (the score at the held fit,
    #                                        or the freed fit's (a - a0)^2 / sigma^2) found no departure


#: What SciPy's least_squares status means, in the words of the fit (its own message names its tolerances).
_VERDICTS = {
    -1: "failed: the problem was ill-posed (improper input to the solver)",
    0: "did not converge: stopped at the evaluation limit",
    1: "converged: the gradient vanished",
    2: "converged: the cost stopped falling",
    3: "converged: the parameters stopped moving",
    4: "converged: the cost and the parameters stopped changing",
}


def solver_verdict(status: int, evaluations: int) -> str:
    """One line on how the bundle adjustment ended: SciPy's ``least_squares`` ``status`` and its number of
    function ``evaluations``, e.g. ``converged: the cost stopped falling (23 evaluations)``."""
    return f"{_VERDICTS.get(int(status), f'ended with solver status {status}')} ({int(evaluations)} evaluations)"


#: OpenCV's distortion terms, in :attr:`psvs.optics.rig.Camera.distortion`'s order.
_LENS_TERMS = ("k1", "k2", "p1", "p2", "k3")
#: The box's rotation vector (rad), in :attr:`psvs.optics.rig.Mirrors.box_rotation_rad`'s order.
_BOX_TERMS = ("box_x_rad", "box_y_rad", "box_z_rad")


def rig_values(rig: Rig) -> dict[str, float]:
    """The calibrated parameters of a rig by name (the keys of :data:`RIG_PARAMS`, in its order; tilts in rad,
    lengths in mm, the principal point in px)."""
    c, m = rig.camera, rig.mirrors
    named = {"focal_length_mm": c.focal_length_mm, "cx_px": c.principal_point_px[0],
             "cy_px": c.principal_point_px[1], "pixel_aspect": c.pixel_pitch_mm[1] / c.pixel_pitch_mm[0],
             **dict(zip(_LENS_TERMS, c.distortion, strict=True)),
             "plate_thickness_mm": m.plate_thickness_mm, "baseline_mm": m.baseline_mm,
             **dict(zip(_BOX_TERMS, m.box_rotation_rad, strict=True))}
    for name in MIRROR_NAMES:
        err = m.error(name)
        named[f"{name}_tilt_a_rad"], named[f"{name}_tilt_b_rad"] = err.tilt_rad
        named[f"{name}_shift_mm"] = err.shift_mm
    return {p: float(named[p]) for p in RIG_PARAMS}


def rig_from_values(values: dict, start: Rig) -> Rig:
    """``start`` with every parameter of :data:`RIG_PARAMS` set from ``values`` (name -> value; tilts in rad).
    The pixel's width stays ``start``'s and its height is the width times ``pixel_aspect``. The plate's
    thickness is clipped at 0 mm, and the plate's refraction terms l, m are derived again from the new plate
    (a calibrated rig carries no override); ValueError naming a missing parameter."""
    missing = [p for p in RIG_PARAMS if p not in values]
    if missing:
        raise ValueError(f"rig parameter {missing[0]} is missing")
    v = {p: float(values[p]) for p in RIG_PARAMS}
    errors = {name: MirrorError((v[f"{name}_tilt_a_rad"], v[f"{name}_tilt_b_rad"]), v[f"{name}_shift_mm"])
              for name in MIRROR_NAMES}
    pitch_x = start.camera.pixel_pitch_mm[0]
    rig = start.replace(focal_length_mm=v["focal_length_mm"], principal_point_px=(v["cx_px"], v["cy_px"]),
                        pixel_pitch_mm=(pitch_x, pitch_x * v["pixel_aspect"]),
                        distortion=tuple(v[p] for p in _LENS_TERMS),
                        plate_thickness_mm=max(v["plate_thickness_mm"], 0.0), baseline_mm=v["baseline_mm"],
                        box_rotation_rad=tuple(v[p] for p in _BOX_TERMS), refraction_l_mm=None, refraction_m_mm=None)
    return rig.with_errors(errors)


def rig_vector(rig: Rig) -> np.ndarray:
    """The calibrated parameters of a rig as a vector, shape (len(RIG_PARAMS),): entry k is the parameter
    named ``RIG_PARAMS[k]`` (:func:`rig_values`)."""
    values = rig_values(rig)
    return np.array([values[p] for p in RIG_PARAMS])


def rig_from_vector(x: np.ndarray, start: Rig) -> Rig:
    """``start`` with the calibrated parameters set from ``x``, shape (len(RIG_PARAMS),), entry k the
    parameter named ``RIG_PARAMS[k]`` (:func:`rig_from_values`)."""
    x = np.asarray(x, dtype=float)
    if x.shape != (len(RIG_PARAMS),):
        raise ValueError(f"a rig vector holds {len(RIG_PARAMS)} parameters, got shape {x.shape}")
    return rig_from_values(dict(zip(RIG_PARAMS, x, strict=True)), start)


def initial_grid_pose(view: GridView, rig: Rig) -> np.ndarray:
    """Target pose (6,: rotation vector, translation mm, target -> frame C) from the right view alone:
    the right view is a pinhole camera (two mirrors), so OpenCV's PnP on it, moved into frame C."""
    import cv2
    c = rig.camera
    K = np.array([[c.focal_length_mm / c.pixel_pitch_mm[0], 0, c.principal_point_px[0]],
                  [0, c.focal_length_mm / c.pixel_pitch_mm[1], c.principal_point_px[1]], [0, 0, 1.0]])
    ok, rvec, tvec = cv2.solvePnP(view.object_mm.astype(np.float64), view.right.astype(np.float64), K,
                                  np.array(c.distortion), flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise ValueError(f"{view.name}: the target fits no pose")
    R_view = direction_map(rig, "right")                    # d_out = R d_cam
    R = R_view @ Rotation.from_rotvec(rvec.ravel()).as_matrix()
    t = R_view @ tvec.ravel() + virtual_centre(rig, "right")
    return np.concatenate([Rotation.from_matrix(R).as_rotvec(), t])


def initial_sweep(views: list[SweepView], local_mm: np.ndarray, rig: Rig) -> np.ndarray:
    """Sweep parameters (offset, ry, rz, x0, y0) from the right view alone: each image's depth from the
    apparent first-to-last length of the pattern (pinhole at O2), the offset their mean difference from
    the robot readings, the lateral position from the right view's pattern centre."""
    c = rig.camera
    span = np.linalg.norm(local_mm[-1] - local_mm[0])
    zs, xy = [], []
    o2, R = virtual_centre(rig, "right"), direction_map(rig, "right")
    for v in views:
        length_mm = np.linalg.norm((v.right[-1] - v.right[0]) * c.pixel_pitch_mm)
        depth = c.focal_length_mm * span / length_mm                   # along the view's axis from O2
        ray = np.array([*((v.right.mean(axis=0) - c.principal_point_px) * c.pixel_pitch_mm), c.focal_length_mm])
        p = o2 + R @ (ray / ray[2] * depth)
        zs.append(p[2] - v.position_mm)
        xy.append(p[:2])
    x0, y0 = np.mean(xy, axis=0)
    start = {"offset_mm": float(np.mean(zs)), "ry_rad": 0.0, "rz_rad": 0.0, "x0_mm": x0, "y0_mm": y0}
    return np.array([start[p] for p in SWEEP_PARAMS])


def _sweep_points(s: np.ndarray, positions: np.ndarray, local_mm: np.ndarray) -> np.ndarray:
    """The sweep pattern's points in frame C (mm), shape (len(positions) * len(local_mm), 3): ``s`` holds
    the sweep's parameters (:data:`SWEEP_PARAMS` order), ``positions`` the robot's Z readings (mm)."""
    p = dict(zip(SWEEP_PARAMS, s, strict=True))
    R = Rotation.from_euler("zy", [p["rz_rad"], p["ry_rad"]]).as_matrix()
    pts = local_mm @ R.T
    if not len(positions):
        return np.zeros((0, 3))
    return np.concatenate([pts + [p["x0_mm"], p["y0_mm"], z + p["offset_mm"]] for z in positions])


class BundleProblem:
    """The residual function and its Jacobian over x = [the free rig parameters (those of :data:`RIG_PARAMS`
    not held, in its order), the sweep's :data:`SWEEP_PARAMS` (if any), 6 pose terms per grid view (rotation
    vector rad, translation mm)]."""

    def __init__(self, grids, sweeps, local_mm, start: Rig, hold=()):
        self.grids, self.sweeps, self.local, self.start = grids, sweeps, local_mm, start
        self.free = np.array([p not in hold for p in RIG_PARAMS])   # held parameters stay at the start
        self.n_rig = int(self.free.sum())
        self.n_sweep = len(SWEEP_PARAMS) if sweeps else 0
        self.full_start = rig_vector(start)
        self.x_start = self.full_start[self.free]
        self.names = [p for p, f in zip(RIG_PARAMS, self.free, strict=True) if f]
        self.sigma = np.array([PRIOR_SIGMA[p] for p in self.names])
        self.obs = np.concatenate([np.concatenate([g.left for g in grids] + [s.left for s in sweeps]),
                                   np.concatenate([g.right for g in grids] + [s.right for s in sweeps])])
        counts = [len(g.object_mm) for g in grids] + [len(s.left) for s in sweeps]
        self.owner = np.repeat(np.arange(len(counts)), counts)           # image index of each point
        self.n_points = int(sum(counts))
        self.positions = np.array([s.position_mm for s in sweeps])
        self._grid_object = np.concatenate([g.object_mm for g in grids]) if grids else np.zeros((0, 3))
        self._grid_owner = self.owner[:len(self._grid_object)]

    def rig(self, x) -> Rig:
        """The rig of ``x``: the start rig with the free parameters set from ``x``."""
        full = self.full_start.copy()
        full[self.free] = x[:self.n_rig]
        return rig_from_vector(full, self.start)

    def split(self, x):
        """``x`` as (the free rig parameters, the sweep's parameters, the poses (n_grids, 6))."""
        r = x[:self.n_rig]
        s = x[self.n_rig:self.n_rig + self.n_sweep]
        poses = x[self.n_rig + self.n_sweep:].reshape(-1, 6)
        return r, s, poses

    def points(self, x) -> np.ndarray:
        """Every target point (n_points, 3) mm in frame C at ``x``: the grid views' (each moved by its pose), then
        the sweep's."""
        _, s, poses = self.split(x)
        parts = []
        if self.grids:
            R = Rotation.from_rotvec(poses[:, :3]).as_matrix()                 # (n_grids, 3, 3), one call
            parts.append(np.einsum("nij,nj->ni", R[self._grid_owner], self._grid_object) + poses[self._grid_owner, 3:])
        if self.sweeps:
            parts.append(_sweep_points(s, self.positions, self.local))
        return np.concatenate(parts)

    def project(self, x, starts=None) -> np.ndarray:
        """Image residuals (2 * n_points, 2): left view rows first, px; ``starts``: camera rays (left, right) to
        start each view's projection from (:func:`psvs.optics.project.project_from`)."""
        return self._views(self.rig(x), self.points(x), starts)[0]

    def _views(self, rig: Rig, pts: np.ndarray, starts=None) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
        out, rays, seen = [], [], []
        for k, view in enumerate(("left", "right")):
            uv, ok, dirs = project_from(pts, rig, view, None if starts is None else starts[k])
            uv[~ok] = np.nan
            out.append(uv)
            rays.append(dirs)
            seen.append(ok)
        r = np.concatenate(out) - self.obs
        r[~np.isfinite(r)] = _MISS_PX
        return r, rays, np.concatenate(seen)

    def _pixels(self, x, rays: list[np.ndarray], seen: np.ndarray) -> np.ndarray:
        """The pixels (2 * n_points, 2) of the camera rays ``rays`` (left, right) through the lens of ``x``'s rig,
        0 on the rows the optics do not reach (their residual is a constant)."""
        cam = self.rig(x).camera
        uv = np.concatenate([pixels_from_camera_dirs(d, cam) for d in rays])
        uv[~seen] = 0.0
        return uv

    def residuals(self, x) -> np.ndarray:
        """The image residuals (4 * n_points,) px, then the priors' (n_rig,) scaled to the detections' noise."""
        prior = NOISE_PX * (x[:self.n_rig] - self.x_start) / self.sigma
        return np.concatenate([self.project(x).ravel(), prior])

    def jacobian(self, x) -> np.ndarray:
        """d residuals / d x (4 * n_points + n_rig, len(x)), forward differences (each step's truncation, h times
        the second derivative, is far below the projection's 1e-10 px over the step). The mirrors' and the
        plate's columns project every point again (from the rays ``x``'s converged to: a few steps fewer); the
        lens's move no ray, only the pixel a ray lands on (:meth:`_pixels`); the poses' are the projection's
        derivative by the point (three projections, not one per pose term) times the point's by the pose. A row
        whose point the step takes across a glass's edge (seen at one end of the step only) is 0 in that
        column, not the miss's constant residual less its own over the step."""
        n_img_rows = 4 * self.n_points
        J = np.zeros((n_img_rows + self.n_rig, len(x)))
        names = self.names + list(SWEEP_PARAMS[:self.n_sweep])
        rig, pts = self.rig(x), self.points(x)
        r0, base, seen = self._views(rig, pts)
        pix0 = self._pixels(x, base, seen)
        for k, name in enumerate(names):
            h = DIFF_STEP[name]
            dx = np.zeros(len(x))
            dx[k] = h
            if name in LENS_PARAMS:
                diff = self._pixels(x + dx, base, seen) - pix0
            else:
                diff = self._stepped(self.rig(x + dx), self.points(x + dx), base, (r0, seen))
            J[:n_img_rows, k] = (diff / h).ravel()
        if self.grids:
            self._pose_columns(x, J, rig, pts, (r0, seen), base)
        J[n_img_rows + np.arange(self.n_rig), np.arange(self.n_rig)] = NOISE_PX / self.sigma
        return J

    def _stepped(self, rig: Rig, pts: np.ndarray, base, at_x: tuple) -> np.ndarray:
        """The image residuals (2 * n_points, 2) through ``rig`` at the points ``pts`` (a step's) less those at x
        (``at_x`` = (residuals, rows seen)), projected from ``base``'s rays; 0 on a row whose point the step takes
        across a glass's edge (seen at one end of the step only): no derivative there, not the miss's constant
        residual less its own."""
        r0, seen = at_x
        r, _, stepped = self._views(rig, pts, base)
        return np.where((stepped == seen)[:, None], r - r0, 0.0)

    def _pose_columns(self, x, J: np.ndarray, rig: Rig, pts: np.ndarray, at_x: tuple, base) -> None:
        """The grid views' pose columns of :meth:`jacobian`, in place: d uv / d pose = (d uv / d point) (d point /
        d pose), each image's rows in its own pose's six columns (``pts``, ``at_x`` = (residuals, rows seen) and
        ``base``: the points, the projection and the rays at ``x``)."""
        by_point = []                                   # d uv / d point: (2 n_points, 2) per axis
        for axis in range(3):
            dp = np.zeros_like(pts)
            dp[:, axis] = _POINT_STEP_MM
            by_point.append(self._stepped(rig, pts + dp, base, at_x) / _POINT_STEP_MM)
        first = self.n_rig + self.n_sweep
        grid_points = np.flatnonzero(self.owner < len(self.grids))
        for q, h in enumerate(POSE_STEP):
            dx = np.zeros(len(x))
            dx[first + q::6] = h
            moved = (self.points(x + dx) - self.points(x - dx))[grid_points] / (2 * h)    # (n_grid, 3)
            cols = first + 6 * self.owner[grid_points] + q
            for view in range(2):
                rows = grid_points + view * self.n_points
                diff = sum(by_point[a][rows] * moved[:, a:a + 1] for a in range(3))          # (n_grid, 2)
                J[2 * rows, cols] = diff[:, 0]
                J[2 * rows + 1, cols] = diff[:, 1]


@one_blas_thread()     # the same numbers on any core count
def bundle_adjust(grids: list[GridView], sweeps: list[SweepView], start: Rig,
                  sweep_local_mm: np.ndarray | None = None, max_nfev: int = 60, hold=None,
                  init: Rig | None = None, loss_scale_px: float = LOSS_SCALE_PX) -> BundleResult:
    """Calibrate a build from grid views and/or sweep views, starting from ``start`` (the nominal design).

    Parameters
    ----------
    grids : list of GridView
        Hand-held views of a planar target (free poses).
    sweeps : list of SweepView
        The paper's robot sweep: one pattern pose, moved along Z by the robot.
    start : Rig
        The nominal design; also the centre of the priors.
    sweep_local_mm : ndarray, shape (k, 3)
        The sweep pattern's points in its own frame (the paper's row of circles), mm.
    hold : iterable of str, optional
        Parameters held at the start rig's values. Default with grid views: the pixel's aspect only, and
        then freed too where the views show it (:func:`aspect_score` beyond :data:`ASPECT_SCORE_LIMIT`; the
        result's ``aspect_score`` says when it was held so); ``()`` frees everything. With a sweep alone (five
        circles in a row cannot see the lens's higher terms, nor tell most mirror errors from the principal
        point and the pattern's pose): first :data:`DESIGN_HOLDS` (the design's mirrors, as the paper's
        model), and only if that leaves the images unexplained (RMS > :data:`DESIGN_FITS_PX`) again with
        the mirror errors free, :data:`SWEEP_HOLDS`.
    init : Rig, optional
        Where the solver starts (e.g. an earlier adjustment of a subset of the images); the priors stay
        centred on ``start``. Default: ``start``.
    loss_scale_px : float
        The soft-L1 loss's scale: residuals beyond it count as outliers (:data:`LOSS_SCALE_PX`); one beyond
        every residual makes the fit plain least squares (:data:`PLAIN_SCALE_PX`).
    """
    if len(grids) + len(sweeps) < 3:
        raise ValueError(f"calibration needs at least 3 usable images, got {len(grids) + len(sweeps)}")
    if sweeps and sweep_local_mm is None:
        raise ValueError("sweep views need the pattern's layout (sweep_local_mm)")
    local = np.zeros((0, 3)) if sweep_local_mm is None else np.asarray(sweep_local_mm, float)
    if hold is None and not grids:
        first = bundle_adjust(grids, sweeps, start, sweep_local_mm, max_nfev, hold=DESIGN_HOLDS, init=init,
                              loss_scale_px=loss_scale_px)
        if first.rms_px <= DESIGN_FITS_PX:
            return first
        hold = SWEEP_HOLDS
    if hold is None:                       # the pixel's aspect freed only where the views show it
        prob = BundleProblem(grids, sweeps, local, start, (ASPECT,))
        sol = _solve(prob, init, max_nfev, loss_scale_px)
        held = _result(prob, sol)
        if held.rms_px > LOSS_SCALE_PX:    # views the fit does not explain yet: no evidence of the aspect's
            return held
        score = aspect_score(prob, sol.x, loss_scale_px)
        if score <= ASPECT_SCORE_LIMIT:
            return _aspect_held(held, score)
        free = BundleProblem(grids, sweeps, local, start, ())       # from where the held fit ended, poses and all
        x0 = np.insert(sol.x, free.names.index(ASPECT), free.x_start[free.names.index(ASPECT)])
        freed = _result(free, _solve(free, init, max_nfev, loss_scale_px, x0))
        wald = ((freed.values[ASPECT] - rig_values(start)[ASPECT]) / max(freed.sigma[ASPECT], 1e-300)) ** 2
        if wald > ASPECT_SCORE_LIMIT:      # and where it ends, the aspect stands apart from the start's too
            return freed
        # (views turned 180 deg, fitted on from where the held fit stopped at 0.2 px, reached 0.04 px with the
        # aspect 1.3 of its sigmas from square and f 1 % off: no evidence of the aspect, and the held fit's misfit
        # is the views' own)
        return _aspect_held(held, wald)
    prob = BundleProblem(grids, sweeps, local, start, tuple(hold or ()))
    return _result(prob, _solve(prob, init, max_nfev, loss_scale_px))


def _aspect_held(held: BundleResult, score: float) -> BundleResult:
    """The fit that held the pixel's aspect, where the views show no other (``score``: the test that found none):
    the aspect is then no parameter the data left unpinned."""
    return replace(held, held_by_prior=tuple(p for p in held.held_by_prior if p != ASPECT), aspect_score=score)


def _solve(prob: BundleProblem, init: Rig | None, max_nfev: int, loss_scale_px: float, x0: np.ndarray | None = None):
    """One bundle adjustment (:func:`bundle_adjust`) of ``prob`` from ``x0`` (its vector) or else from ``init``
    (or the start rig) and each view's pose it implies: SciPy's solution."""
    start = prob.start
    first_guess = start if init is None else init
    if x0 is None:
        x0 = [rig_vector(first_guess)[prob.free]]
        if prob.sweeps:
            x0.append(initial_sweep(prob.sweeps, prob.local, first_guess))
        x0 += [initial_grid_pose(g, first_guess) for g in prob.grids]
        x0 = np.concatenate(x0)
    x0 = np.array(x0, dtype=np.float64)
    lo, hi = np.full(len(x0), -np.inf), np.full(len(x0), np.inf)
    for k, name in enumerate(prob.names):
        lo[k], hi[k] = _bounds(name, prob.x_start[k], start)
    pad = 1e-9 * (hi[:prob.n_rig] - lo[:prob.n_rig])
    x0[:prob.n_rig] = np.clip(x0[:prob.n_rig], lo[:prob.n_rig] + pad, hi[:prob.n_rig] - pad)
    sol = least_squares(prob.residuals, x0, jac=prob.jacobian, bounds=(lo, hi), method="trf", loss="soft_l1",
                        f_scale=loss_scale_px, x_scale="jac", max_nfev=max_nfev, tr_solver="exact")
    return sol


def aspect_score(prob: BundleProblem, x: np.ndarray, loss_scale_px: float) -> float:
    """Rao's score statistic for freeing the pixel's aspect at the solution ``x`` of ``prob`` (which holds it at
    the start rig's): g' (J'WJ)^-1 g / s^2 over every parameter, the aspect's column added, with g = J'W r the
    cost's gradient there, W the soft-L1 loss's weights (1 / sqrt(1 + (r / scale)^2)) and s^2 the image
    residuals' variance. About chi-square with 1 degree of freedom where the views show no departure (the
    other parameters' gradients are zero at ``x``)."""
    held = tuple(p for p in RIG_PARAMS if not prob.free[RIG_PARAMS.index(p)] and p != ASPECT)
    free = BundleProblem(prob.grids, prob.sweeps, prob.local, prob.start, held)
    k = free.names.index(ASPECT)
    xf = np.insert(x, k, free.x_start[k])
    r, J = free.residuals(xf), free.jacobian(xf)
    w = 1.0 / np.sqrt(1.0 + (r / loss_scale_px) ** 2)
    g = J.T @ (w * r)
    n_img = 4 * free.n_points
    s2 = max(float(np.sum(w[:n_img] * r[:n_img] ** 2)) / max(1, n_img - len(xf) + free.n_rig), 1e-12)
    return float(g @ covariance(J * np.sqrt(w)[:, None]) @ g / s2)


def _bounds(name: str, value: float, start: Rig) -> tuple[float, float]:
    """Physical limits of a parameter, so the solver never leaves the optics' domain (f > 0, ...)."""
    w, h = start.camera.image_size_px
    if name == "focal_length_mm":
        return 0.5 * value, 2.0 * value
    if name == "cx_px":
        return 0.0, w - 1.0
    if name == "cy_px":
        return 0.0, h - 1.0
    if name == "pixel_aspect":
        return 0.8 * value, 1.25 * value
    if name == "plate_thickness_mm":
        return 0.0, max(10.0, 3 * value)
    if name == "baseline_mm":
        return 0.3 * value, 3.0 * value
    if "tilt" in name or name.startswith("box"):
        return -0.1, 0.1          # rad: +-5.7 deg
    if "shift" in name:
        return -20.0, 20.0
    return (-2.0, 2.0) if name in ("k1", "k2", "k3") else (-0.2, 0.2)


def covariance(J: np.ndarray) -> np.ndarray:
    """(J^T J)^-1 (n, n) of a Jacobian (m, n), through its columns scaled to unit length: the parameters' units
    (mm, rad, px, k's) put the unscaled normal matrix's condition near 1e16, where a pseudo-inverse drops a
    weakly pinned combination as if it had no variance at all (an adversarial trial: cards held square to the
    camera, along whose f-distance valley the fit's cost changes by 0.2 chi-square over 6 %, stated f to
    +-0.02 %, 123 sigma from the truth; scaled, +-4.8 %). Scaled, the condition is about 1e9."""
    A = J.T @ J
    d = np.sqrt(np.diag(A))
    d[d == 0] = 1.0                     # a column no row sees: its own (infinite) variance stays undefined
    scaled = A / np.outer(d, d)
    return np.linalg.pinv(scaled, rcond=1e-13, hermitian=True) / np.outer(d, d)


def _result(prob: BundleProblem, sol) -> BundleResult:
    x = sol.x
    img = prob.project(x)                                   # (2 n_points, 2)
    n = prob.n_points
    names = prob.names + list(SWEEP_PARAMS[:prob.n_sweep])
    J = prob.jacobian(x)
    k = len(names)
    dof = max(1, img.size - len(x) + prob.n_rig)
    s2 = max(float(np.sum(img ** 2)) / dof, 1e-12)
    cov = covariance(J) * s2
    sig = np.sqrt(np.clip(np.diag(cov)[:k], 0, None))
    # what the data did not pin down: held on purpose, or its posterior sigma is still over half its prior's
    sigma = dict(zip(names, map(float, sig), strict=True))
    held = tuple(p for p in RIG_PARAMS if p not in sigma or sigma[p] > 0.5 * PRIOR_SIGMA[p])
    full_cov = np.zeros((len(RIG_PARAMS), len(RIG_PARAMS)))
    idx = np.flatnonzero(prob.free)
    full_cov[np.ix_(idx, idx)] = cov[:prob.n_rig, :prob.n_rig]
    rig = prob.rig(x)
    sweep_names = names[prob.n_rig:]
    values = rig_values(rig) | dict(zip(sweep_names, map(float, x[prob.n_rig:k]), strict=True))
    sigma = {p: sigma.get(p, 0.0) for p in RIG_PARAMS} | {n: sigma[n] for n in sweep_names}
    labels = [g.name for g in prob.grids] + [s.name for s in prob.sweeps]
    left, right = img[:n], img[n:]
    per_image = {name: float(np.sqrt(np.mean(np.concatenate([left[prob.owner == i], right[prob.owner == i]]) ** 2)))
                 for i, name in enumerate(labels)}
    residuals = {name: (left[prob.owner == i], right[prob.owner == i]) for i, name in enumerate(labels)}
    observed = {name: (prob.obs[:n][prob.owner == i], prob.obs[n:][prob.owner == i]) for i, name in enumerate(labels)}
    _, s, poses = prob.split(x)
    return BundleResult(
        rig=rig, values=values, sigma=sigma, held_by_prior=held,
        rms_px=float(np.sqrt(np.mean(img ** 2))),
        rms_by_view={"left": float(np.sqrt(np.mean(left ** 2))), "right": float(np.sqrt(np.mean(right ** 2)))},
        rms_by_image=per_image, residuals=residuals, observed=observed,
        poses={g.name: transform_from_rotvec(p[:3], p[3:]) for g, p in zip(prob.grids, poses, strict=True)},
        success=bool(sol.success), message=solver_verdict(sol.status, sol.nfev),
        sweep=dict(zip(SWEEP_PARAMS, map(float, s), strict=True)) if prob.n_sweep else {},
        covariance=full_cov)
