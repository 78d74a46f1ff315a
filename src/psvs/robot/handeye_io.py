"""Hand-eye files: the calibrated transform (``handeye.toml``) and a folder of hand-eye views.

``handeye.toml`` (written by ``psvs handeye``, read by ``psvs track --handeye``)::

    [handeye]
    method = "reprojection"      # the discs' reprojection error over cam2flange and the target's pose,
                                 # from Park & Martin's closed form (1994); older files: "park_martin"
    source = "simulated cell"    # or the views folder
    rig = "default"              # the rig the views were triangulated with, by name
    rig_sha256 = "9c1e..."       # and by its values (psvs.io.params.rig_digest; optional: older files lack it)
    views = 12
    cam2flange = [[r00, r01, r02, x_mm], [r10, r11, r12, y_mm], [r20, r21, r22, z_mm], [0.0, 0.0, 0.0, 1.0]]
    target_rms_mm = [...]        # per view: the grid's rigid fit to its triangulated discs
    spread_mm = 0.05             # the target's base pose over the views (consistency)
    spread_deg = 0.02
    reprojection_rms_px = 0.04   # the discs' reprojection RMS in both views at the solution (optional)
    mount_sigma_mm = 1.6         # the mount's 1-sigma from its inputs' noise (optional): position, RMS over
    mount_sigma_deg = 0.6        # the axes, and orientation (psvs.robot.handeye_noise)

frame C (the PSVS) in the flange frame: a 4 x 4 homogeneous transform, rotation and millimetres (the
matrix is kept whole so that a file round-trips exactly; degrees appear only in ``spread_deg``).

A views folder holds the complex images ``view_NN.png``, ``target.toml`` (the circle grid, as for
``psvs calibrate``) and ``flange_poses.csv``: ``image,x_mm,y_mm,z_mm,qx,qy,qz,qw``, each image's flange
pose in the robot's base frame (position mm, unit quaternion, scalar last as in ROS).
"""
from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from psvs.io.atomic import write_atomic
from psvs.io.images import first_repeat, read_grey, write_png
from psvs.io.text import read_csv_rows
from psvs.io.tomlfile import dumps_toml, load_table
from psvs.robot.handeye import HandEyeResult
from psvs.simulate.textures import CircleGrid
from psvs.targets.target_file import dumps_target, load_target
from psvs.transforms import check_transform, transform_from

METHOD = "reprojection"
#: Methods a file may name: this psvs's, and the closed form alone that earlier versions wrote.
METHODS = (METHOD, "park_martin")
_KEYS = ("method", "source", "rig", "views", "cam2flange", "target_rms_mm", "spread_mm", "spread_deg")
_OPTIONAL = ("reprojection_rms_px", "mount_sigma_mm", "mount_sigma_deg", "rig_sha256")
POSES_CSV = "flange_poses.csv"
POSE_COLUMNS = ("image", "x_mm", "y_mm", "z_mm", "qx", "qy", "qz", "qw")


def dumps_handeye(result: HandEyeResult, source: str, rig: str) -> str:
    """The ``handeye.toml`` text of a calibration through the rig named ``rig`` (read back exactly by
    :func:`load_handeye`); the rig's values by ``result.rig_sha256`` when known."""
    data = {"handeye": {
        "method": METHOD, "source": str(source), "rig": str(rig), "views": int(len(result.target_rms_mm)),
        "cam2flange": [[float(x) for x in row] for row in result.cam2flange],
        "target_rms_mm": [float(x) for x in result.target_rms_mm],
        "spread_mm": float(result.spread_mm), "spread_deg": math.degrees(result.spread_rad)}}
    if result.reprojection_rms_px is not None:
        data["handeye"]["reprojection_rms_px"] = float(result.reprojection_rms_px)
    if result.mount_sigma_mm is not None and result.mount_sigma_rad is not None:
        data["handeye"]["mount_sigma_mm"] = float(result.mount_sigma_mm)
        data["handeye"]["mount_sigma_deg"] = math.degrees(result.mount_sigma_rad)
    if result.rig_sha256 is not None:
        data["handeye"]["rig_sha256"] = str(result.rig_sha256)
    return ("# psvs handeye: frame C (the PSVS) in the flange frame; rotation and mm (docs/robot.md)\n"
            + dumps_toml(data))


def save_handeye(path, result: HandEyeResult, source: str, rig: str) -> None:
    """Write a hand-eye result to ``path`` as handeye.toml (:func:`dumps_handeye`, naming its ``source`` and
    ``rig``), atomically; :func:`load_handeye` reads it back."""
    write_atomic(Path(path), dumps_handeye(result, source, rig))


def load_handeye(path) -> HandEyeResult:
    """A ``handeye.toml``; ValueError naming the file and the key when it is not one."""
    return load_table(path, "hand-eye", "handeye", _KEYS, _OPTIONAL, parse=_handeye)


def _handeye(h: dict) -> HandEyeResult:
    if h["method"] not in METHODS:
        raise ValueError(f"handeye.method must be one of {', '.join(map(repr, METHODS))}, got {h['method']!r}")
    X = _numbers(h["cam2flange"], "cam2flange")
    if X.shape != (4, 4):
        raise ValueError(f"handeye.cam2flange must be 4 rows of 4 numbers, got shape {X.shape}")
    check_transform(X, "handeye.cam2flange")
    rms = _numbers(h["target_rms_mm"], "target_rms_mm").ravel()
    if isinstance(h["views"], bool) or not isinstance(h["views"], int) or h["views"] != len(rms) or len(rms) < 3:
        raise ValueError(f"handeye.views must be the number of target_rms_mm values (>= 3), got {h['views']!r}")
    spreads = [_numbers(h[k], k).item() for k in ("spread_mm", "spread_deg")]
    digest = h.get("rig_sha256")
    if digest is not None and not (isinstance(digest, str) and re.fullmatch("[0-9a-f]{64}", digest)):
        raise ValueError(f"handeye.rig_sha256 must be 64 hex digits (psvs handeye writes it), got {digest!r}")
    extra = {k: _numbers(h[k], k).item() for k in _OPTIONAL if k in h and k != "rig_sha256"}
    if np.any(rms < 0) or min(spreads + list(extra.values())) < 0:
        raise ValueError("handeye residuals and uncertainties must be >= 0")
    if ("mount_sigma_mm" in extra) != ("mount_sigma_deg" in extra):
        raise ValueError("handeye.mount_sigma_mm and handeye.mount_sigma_deg go together: give both or neither")
    sigma_deg = extra.get("mount_sigma_deg")
    return HandEyeResult(X, rms, spreads[0], math.radians(spreads[1]), extra.get("reprojection_rms_px"),
                         mount_sigma_mm=extra.get("mount_sigma_mm"),
                         mount_sigma_rad=None if sigma_deg is None else math.radians(sigma_deg), rig_sha256=digest)


def check_same_rig(result: HandEyeResult, rig_sha256: str, where: str, rig_name: str) -> None:
    """ValueError (exit 2) when a hand-eye result was calibrated through a rig of other values than the one
    it is about to serve (``rig_sha256``: :func:`psvs.io.params.rig_digest` of it): the mount is frame C's
    pose as that rig triangulated the target, and another camera, baseline or refit gives another (an
    adversarial trial: an mv1440 mount tracked through the paper's rig without a word). Nothing to check on
    a file that does not name its rig's values (older files)."""
    if result.rig_sha256 is not None and result.rig_sha256 != rig_sha256:
        raise ValueError(f"{where} was calibrated through a rig of other values than {rig_name}: its mount is "
                         f"not this rig's; calibrate it through this one (psvs handeye --rig ...)")


def _numbers(value, key: str) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"handeye.{key} must hold numbers, got {value!r}") from None
    if any(isinstance(x, bool) for x in np.ravel(np.array(value, dtype=object))) or not np.all(np.isfinite(arr)):
        raise ValueError(f"handeye.{key} must hold finite numbers, got {value!r}")
    return arr


def write_views(folder, images: list[np.ndarray], flange2base: list[np.ndarray], grid: CircleGrid) -> None:
    """A hand-eye views folder (see the module docstring), each file written atomically."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(POSE_COLUMNS)
    for k, (img, F) in enumerate(zip(images, flange2base, strict=True)):
        name = f"view_{k:02d}.png"
        write_png(folder / name, img)
        q = Rotation.from_matrix(F[:3, :3]).as_quat()
        w.writerow([name, *(repr(float(x)) for x in F[:3, 3]), *(repr(float(x)) for x in q)])
    write_atomic(folder / "target.toml", dumps_target(grid))
    write_atomic(folder / POSES_CSV, buf.getvalue())


def read_views(folder, expect_size: tuple[int, int] | None = None
               ) -> tuple[list[np.ndarray], list[np.ndarray], CircleGrid]:
    """(complex images, flange2base (4, 4) mm, the target) of a hand-eye views folder; ValueError naming
    the file and the row when it is not one, or an image is not ``expect_size`` (W, H) px (the camera's)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"hand-eye views folder not found: {folder}")
    grid = load_target(folder / "target.toml")
    poses = folder / POSES_CSV
    if not poses.is_file():
        raise FileNotFoundError(f"{folder} has no {POSES_CSV} (image,x_mm,y_mm,z_mm,qx,qy,qz,qw)")
    rows = read_csv_rows(poses)
    if not rows or tuple(c.strip() for c in rows[0]) != POSE_COLUMNS:
        raise ValueError(f"{poses}: the header must be {','.join(POSE_COLUMNS)}")
    paths, lines, flanges = [], [], []
    seen: dict = {}             # each pose: the line that gave it first
    for n, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(POSE_COLUMNS):
            raise ValueError(f"{poses}: line {n} has {len(row)} fields, not {len(POSE_COLUMNS)}")
        try:
            vals = np.array([float(x) for x in row[1:]])
        except ValueError:
            raise ValueError(f"{poses}: line {n}: not a number in {row[1:]}") from None
        q = vals[3:]
        if not np.all(np.isfinite(vals)) or abs(np.linalg.norm(q) - 1.0) > 1e-3:
            raise ValueError(f"{poses}: line {n}: the position must be finite and the quaternion of unit "
                             f"length (|q| = {np.linalg.norm(q):.4g})")
        F = transform_from(Rotation.from_quat(q / np.linalg.norm(q)).as_matrix(), vals[:3])
        paths.append(folder / row[0].strip())
        lines.append(n)
        flanges.append(F)
    repeat = first_repeat(paths)
    if repeat is not None:
        a, b = repeat
        raise ValueError(f"{poses}: line {lines[b]}: {paths[b].name} is the same photograph as line {lines[a]}'s "
                         "(byte-identical files): each view must be its own photograph of its own robot pose")
    for n, F in zip(lines, flanges, strict=True):
        _check_new_pose(seen, F, f"{poses}: line {n}")
    if len(paths) < 3:
        raise ValueError(f"{poses}: the hand-eye calibration needs >= 3 views, found {len(paths)}")
    return [read_grey(p, expect_size=expect_size) for p in paths], flanges, grid


def _check_new_pose(seen: dict, flange2base: np.ndarray, where: str) -> None:
    """ValueError when a views folder's line repeats an earlier one's robot pose (within 1 um and 1 urad); its
    photographs are checked likewise (:func:`psvs.io.images.first_repeat`): a copy adds no view, yet the fit
    would count it as one, and its stated 1-sigma would shrink with every copy (an adversarial trial: 3 views
    refused as not pinning the mount, the same 3 copied 4 times accepted at half the 1-sigma)."""
    key = tuple(np.round(np.concatenate([flange2base[:3, 3] * 1e3, flange2base[:3, :3].ravel() * 1e6])))
    if key in seen:
        raise ValueError(f"{where}: the flange pose of {seen[key]} again: each view must be its own robot pose")
    seen[key] = f"{where.rsplit(': ', 1)[-1]}'s"
