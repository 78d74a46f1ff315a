"""Calibration from a robot sweep: the paper's circle pattern moved along Z, positions read off the robot.

Unknowns: the camera's focal length f and principal point (cx, cy), the baseline b, the M1 plate's
thickness d (the exact model's refraction; n is kept), the robot's unknown Z offset, and the pattern's
pose on the robot (the direction of its row of circles, angles ry and rz, and its lateral position x0,
y0; constant while the robot moves along Z). A rotation about the row itself cannot be seen in the circle
centres, so it is not a parameter.
Residuals: every detected circle centre (both views) minus the exact projection (issue 2's optics) of
the pattern's circle centre, px. Solved by scipy's least_squares (bounded trust-region, soft-L1 loss) from a
rough start; parameter uncertainties from the Jacobian at the solution.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from psvs.calibrate.targets import detect_pattern
from psvs.io.images import read_grey
from psvs.measure.triangulate import triangulate
from psvs.optics.project import project_points
from psvs.optics.rig import Rig

PARAMS = ("focal_length_mm", "cx_px", "cy_px", "baseline_mm", "plate_thickness_mm", "offset_mm",
          "ry_rad", "rz_rad", "x0_mm", "y0_mm")


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """rig: the calibrated rig; offset_mm: robot Z reading + offset = Z in frame C; values / sigma: every
    parameter and its 1-sigma uncertainty; rms_px: reprojection RMS; used: the images used; skipped:
    {image: reason} for images that could not be used; success, message: from the solver."""

    rig: Rig
    offset_mm: float
    values: dict
    sigma: dict
    rms_px: float
    used: list
    skipped: dict = field(default_factory=dict)
    success: bool = True
    message: str = ""


def read_sweep(folder) -> list[tuple[Path, float]]:
    """(image path, robot position mm) from ``folder/sweep.csv`` (columns image,position_mm)."""
    folder = Path(folder)
    table = folder / "sweep.csv"
    if not table.is_file():
        raise FileNotFoundError(f"sweep file not found: {table}")
    with table.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None or not {"image", "position_mm"} <= set(reader.fieldnames):
            raise ValueError(f"{table}: expected columns image,position_mm, got {reader.fieldnames}")
        out = []
        for n, row in enumerate(reader, start=2):
            try:
                out.append((folder / row["image"], float(row["position_mm"])))
            except ValueError:
                raise ValueError(f"{table}:{n}: position_mm is not a number: {row['position_mm']!r}") from None
    if not out:
        raise ValueError(f"{table}: no images listed")
    return out


def detect_sweep(items: list[tuple[Path, float]], count: int = 5):
    """Detect the pattern in every image; returns ([(name, position, detection)], {name: error})."""
    ok, skipped = [], {}
    for path, pos in items:
        try:
            ok.append((path.name, pos, detect_pattern(read_grey(path), count)))
        except (ValueError, FileNotFoundError) as exc:
            skipped[path.name] = str(exc)
    return ok, skipped


def _rig_from(x, start: Rig) -> Rig:
    return start.replace(focal_length_mm=x[0], principal_point_px=(x[1], x[2]), baseline_mm=x[3],
                         plate_thickness_mm=max(x[4], 0.0), refraction_l_mm=None, refraction_m_mm=None)


def _points(x, positions: np.ndarray, local: np.ndarray) -> np.ndarray:
    R = Rotation.from_euler("zy", [x[7], x[6]]).as_matrix()
    pts = local @ R.T
    return np.concatenate([pts + [x[8], x[9], p + x[5]] for p in positions])


def calibrate_sweep(observations, start: Rig, spacing_mm: float = 20.0, count: int = 5) -> CalibrationResult:
    """Calibrate from detections [(name, robot position mm, PatternDetection)] and a rough start rig."""
    if len(observations) < 3:
        raise ValueError(f"calibration needs at least 3 usable sweep images, got {len(observations)}")
    positions = np.array([p for _, p, _ in observations])
    left = np.concatenate([np.array([e.centre_px for e in d.left]) for _, _, d in observations])
    right = np.concatenate([np.array([e.centre_px for e in d.right]) for _, _, d in observations])
    local = np.column_stack([(np.arange(count) - (count - 1) / 2) * spacing_mm, np.zeros(count), np.zeros(count)])
    # start: offset from the first image's depth with the start rig; pose facing the camera
    first = triangulate(left[:count], right[:count], start, model="exact").points_mm
    c = start.camera
    x0 = np.array([c.focal_length_mm, *c.principal_point_px, start.mirrors.baseline_mm,
                   start.mirrors.plate_thickness_mm, float(np.nanmean(first[:, 2])) - positions[0],
                   0.0, 0.0, float(np.nanmean(first[:, 0])), float(np.nanmean(first[:, 1]))])

    def residuals(x):
        rig = _rig_from(x, start)
        pts = _points(x, positions, local)
        res = []
        for view, obs in (("left", left), ("right", right)):
            uv, ok = project_points(pts, rig, view)
            r = uv - obs
            r[~ok] = 100.0   # a point the optics cannot reach costs like a gross error
            res.append(r.ravel())
        return np.concatenate(res)

    w, h = c.image_size_px
    lo = np.array([0.5 * x0[0], 0.0, 0.0, 0.3 * x0[3], 0.0, -np.inf, -0.6, -0.6, -np.inf, -np.inf])
    hi = np.array([2.0 * x0[0], w - 1.0, h - 1.0, 3.0 * x0[3], 10.0, np.inf, 0.6, 0.6, np.inf, np.inf])
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    scale = np.array([1.0, 50.0, 50.0, 10.0, 1.0, 50.0, 0.05, 0.05, 10.0, 10.0])
    sol = least_squares(residuals, x0, bounds=(lo, hi), x_scale=scale, loss="soft_l1", f_scale=0.5,
                        method="trf", max_nfev=400)
    r = residuals(sol.x)
    dof = max(1, len(r) - len(sol.x))
    sigma2 = float(r @ r) / dof
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * sigma2
        sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        sig = np.full(len(sol.x), np.nan)
    rig = _rig_from(sol.x, start)
    return CalibrationResult(rig, float(sol.x[5]), dict(zip(PARAMS, map(float, sol.x))),
                             dict(zip(PARAMS, map(float, sig))), float(np.sqrt(np.mean(r ** 2))),
                             [n for n, _, _ in observations], {}, bool(sol.success), str(sol.message))


def calibrate_folder(folder, start: Rig, count: int = 5) -> CalibrationResult:
    """Read ``folder/sweep.csv``, detect the pattern in each image (failures are skipped and reported),
    and calibrate."""
    obs, skipped = detect_sweep(read_sweep(folder), count)
    res = calibrate_sweep(obs, start, count=count)
    return CalibrationResult(res.rig, res.offset_mm, res.values, res.sigma, res.rms_px, res.used, skipped,
                             res.success, res.message)

