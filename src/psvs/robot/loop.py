"""Closed-loop seam tracking in the simulated cell: the controller (psvs.robot.controller) run by
:func:`psvs.robot.cells.control_loop` on the simulated PUMA 560 (:class:`psvs.robot.cells.SimulatedCell`):
every control cycle (1 / rate_hz of simulated time) the sensor window is rendered from the camera pose
the arm's joints really give, the seam sensor matches both groove edges with their twins, the controller
turns them into a torch pose, and the arm's IK and servo carry it out. Wall time of each stage is measured.
Also the hand-eye session in the cell, and :func:`replay` of a recorded run.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from psvs.optics.rig import Rig
from psvs.optics.window import roi_rig
from psvs.robot.arm import Arm, ArmLimits
from psvs.robot.cells import CycleResult, Frame, ReplayCell, SimulatedCell, control_loop
from psvs.robot.controller import UP, SeamTracker, TrackConfig
from psvs.robot.handeye import HandEyeResult, calibrate_from_views
from psvs.robot.mounting import MOUNT_ERROR, cam2tool, tool2flange, tool_pose
from psvs.robot.workpiece import Workpiece
from psvs.simulate.render import render
from psvs.simulate.scene import Lighting, Pose, Scene, SceneObject
from psvs.simulate.sequence import scene_in_rig_frame
from psvs.simulate.textures import CircleGrid
from psvs.transforms import invert_transform, transform_from

#: A PUMA 560 configuration (right arm, elbow up) with the torch down over the table; IK starts here.
HOME_Q = np.radians([23.0, 4.5, -168.0, -54.0, -53.0, 161.0])


@dataclass(frozen=True, eq=False)
class Cycle:
    """One control cycle's record (base frame, mm; times s)."""

    t_s: float
    s_mm: float                 # torch progress along the path model
    speed_mm_s: float
    tcp_mm: np.ndarray          # (3,) torch tip reached (true kinematics)
    target_mm: np.ndarray       # (3,) torch tip commanded
    seam_mm: np.ndarray         # (3,) seam root seen this cycle (NaN if none)
    valid: bool
    reason: str
    q: np.ndarray               # (6,) rad
    qd: np.ndarray              # (6,) rad/s
    qdd_peak: np.ndarray        # (6,) rad/s^2
    image: np.ndarray           # (window rows, W) uint8 (roi_rows + the twins' row offset on a build)
    points_mm: np.ndarray       # (N, 3) edge points seen, base frame
    path_mm: np.ndarray         # (M, 3) path model ahead of the torch
    wall_render_s: float
    wall_sensor_s: float
    wall_control_s: float
    flange2base: np.ndarray     # (4, 4) the flange pose at the frame's exposure (the controller's input)
    tool2base: np.ndarray       # (4, 4) the torch pose commanded (the controller's output)
    fault: str = ""             # the arm's refusal of the command ('' none)


@dataclass(frozen=True, eq=False)
class Stop:
    """Why and where the run ended: reason, torch progress (mm), torch tip (3,) mm, the last seam point
    seen (arc length, base point), and the torch progress when the seam was first lost and when the
    stop was decided."""

    reason: str
    s_mm: float
    tcp_mm: np.ndarray
    last_seen_s_mm: float
    last_seen_mm: np.ndarray
    lost_at_s_mm: float | None = None   # torch progress at the first frame without the seam
    decided_at_s_mm: float | None = None  # torch progress when the stop was decided


@dataclass(frozen=True, eq=False)
class TrackRun:
    config: TrackConfig
    cycles: list[Cycle]
    stop: Stop
    handeye: HandEyeResult
    cam2flange_true: np.ndarray
    seed_px: tuple[float, float]
    extras: dict = field(default_factory=dict)


def cell_lighting(cfg: TrackConfig) -> Lighting:
    return Lighting(ambient=0.25, lamp=0.75, reference_mm=cfg.camera_distance_mm)


#: The hand-eye session's target: a 4 x 5 circle grid lying face up on the table.
CELL_GRID = CircleGrid(rows=4, cols=5, spacing_mm=15.0, diameter_mm=7.0)
CELL_TARGET2BASE = transform_from(np.diag([1.0, -1.0, -1.0]), (550.0, 0.0, 0.0))


def nominal_cam2flange(cfg: TrackConfig) -> np.ndarray:
    """Frame C on the flange as the bracket drawing has it (4, 4) mm."""
    return tool2flange() @ cam2tool(cfg.look_ahead_mm, cfg.standoff_mm, cfg.camera_distance_mm)


def true_cam2flange(cfg: TrackConfig) -> np.ndarray:
    """Frame C on the flange as the simulated hardware really has it: the drawing and the bracket's
    error (:data:`psvs.robot.mounting.MOUNT_ERROR`); what a hand-eye calibration should find."""
    return nominal_cam2flange(cfg) @ MOUNT_ERROR


def cell_views(rig: Rig, cfg: TrackConfig, arm: Arm, views: int = 12,
               true_rig: Rig | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The hand-eye session in the simulated cell: :data:`CELL_GRID` on the table shown to the PSVS from
    ``views`` flange poses (tilted up to ~20 deg, turned about the vertical), rendered through ``true_rig``
    (default ``rig``) with the true mounting. Returns (complex images (H, W) uint8, flange2base (4, 4))."""
    if not isinstance(views, int) or views < 3:
        raise ValueError(f"the hand-eye session needs an integer >= 3 views, got {views!r}")
    plate = SceneObject("rectangle", Pose(CELL_TARGET2BASE[:3, :3], CELL_TARGET2BASE[:3, 3]), CELL_GRID,
                        size_mm=(320.0, 320.0), name="target")
    scene = Scene((plate,), cell_lighting(cfg), None)
    nominal, true = nominal_cam2flange(cfg), true_cam2flange(cfg)
    rng = np.random.default_rng(7)
    from scipy.spatial.transform import Rotation
    images, flanges = [], []
    for k in range(views):
        yaw = np.pi / 2 + (k - (views - 1) / 2) * 0.05
        tilt = Rotation.from_rotvec(np.append(rng.uniform(-0.35, 0.35, 2), yaw)).as_matrix()
        cam_R = tilt @ np.diag([1.0, -1.0, -1.0])   # camera looking down, turned and tilted
        cam_pos = CELL_TARGET2BASE[:3, 3] - cfg.camera_distance_mm * cam_R[:, 2] + \
            np.append(rng.uniform(-10, 10, 2), 0)
        flange = transform_from(cam_R, cam_pos) @ invert_transform(nominal)
        F = arm.fkine(arm.ikine(flange, HOME_Q))
        img = render(scene_in_rig_frame(scene, invert_transform(F @ true)), true_rig or rig, supersample=1,
                     seed=100 + k).image
        images.append(img)
        flanges.append(F)
    return images, flanges


def calibrate_cell(rig: Rig, cfg: TrackConfig, arm: Arm, views: int = 12,
                   true_rig: Rig | None = None) -> tuple[HandEyeResult, np.ndarray]:
    """Hand-eye calibration session in the simulated cell (:func:`cell_views`), calibrated with ``rig``,
    what the sensor knows of the rig; returns the result and the true cam2flange of the simulated hardware."""
    images, flanges = cell_views(rig, cfg, arm, views, true_rig)
    he = calibrate_from_views(images, flanges, rig, CELL_GRID, nominal_cam2flange(cfg), CELL_TARGET2BASE)
    return he, true_cam2flange(cfg)


def track(workpiece: Workpiece, rig: Rig, cfg: TrackConfig = TrackConfig(), seed_px=None,
          limits: ArmLimits = ArmLimits(), handeye: tuple[HandEyeResult, np.ndarray] | None = None,
          progress=None, true_rig: Rig | None = None, on_start=None) -> TrackRun:
    """Run the closed loop on the workpiece until the torch stops; see the module docstring.

    Parameters
    ----------
    workpiece : Workpiece (base frame)
    rig : Rig (the full camera; the sensor reads ``cfg.roi_rows`` rows of it): what the sensor knows
    true_rig : Rig or None
        The rig as built, through which the world is rendered (default ``rig``): e.g. the build's true
        geometry while the sensor uses only what was calibrated from images, as on real glass.
    seed_px : (u, v) or None
        A pixel inside the left view's groove in the first ROI frame (teaching by showing); None: found
        by :func:`psvs.robot.sensor.auto_seed`.
    handeye : (HandEyeResult, true cam2flange) or None to run :func:`calibrate_cell` first.
    progress : callable(Cycle) or None, called after every cycle.
    on_start : callable(cam2flange (4, 4), taught_mm (3,), travel (3,)) or None, called once before the
        first cycle with what the controller starts from (e.g. to record it).
    """
    t_enter = time.perf_counter()
    arm = Arm(HOME_Q, limits)
    he, cam_true = handeye if handeye is not None else calibrate_cell(rig, cfg, arm, true_rig=true_rig)
    # the operator jogs the torch to the seam's start (a teach point, 0.3 mm off the seam) and teaches the
    # direction of travel: the only use of the true seam in the loop (scoring aside)
    x0 = workpiece.x_range_mm[0] + cfg.start_offset_mm
    p0, p1 = workpiece.seam_base([x0, x0 + 1.0])
    travel = (p1 - p0) / np.linalg.norm(p1 - p0)
    taught = p0 + 0.3 * np.cross(UP, travel)
    arm.q = arm.ikine(tool_pose(taught + cfg.standoff_mm * UP, travel) @ invert_transform(tool2flange()), HOME_Q)
    near, far = sensor_range(cfg)
    # the sensor window (taller on a build: the twins' rows differ), decided from what the sensor knows
    roi, v0 = roi_rig(rig, cfg.roi_rows, span_mm=(near, far))
    roi_true = roi if true_rig is None else roi_rig(true_rig, roi.camera.image_size_px[1], v0)[0]  # same rows
    tracker = SeamTracker(cfg, he.cam2flange, taught, travel, window_length_mm(rig, cfg))
    cell = SimulatedCell(arm, workpiece, roi_true, cam_true, cfg.rate_hz, cfg.supersample, cfg.noise_seed)
    cycles: list[Cycle] = []
    if on_start is not None:
        on_start(he.cam2flange, taught, travel)

    def record(res: CycleResult) -> None:
        c, step = res.command, res.step
        cyc = Cycle(res.frame.t_s, c.s_mm, tracker.v, cell.tcp_mm(), c.target_mm, c.seam_mm, c.valid, c.reason,
                    step.q, step.qd, step.qdd_peak, res.frame.image, c.points_mm, c.path_mm, *res.wall_s,
                    res.frame.flange2base, c.tool2base, res.fault)
        cycles.append(cyc)
        if progress is not None:
            progress(cyc)

    max_cycles = int((workpiece.params["length_mm"] + 100) / cfg.speed_mm_s * cfg.rate_hz * 2) + 200
    start_s = time.perf_counter() - t_enter   # set-up (hand-eye calibration included) until the first cycle
    _, sensor, seed_px = control_loop(cell, tracker, roi, near, far, seed_px, max_cycles, record)
    stop_reason = tracker.stop_reason if tracker.stopped and cell.at_rest() else \
        (tracker.stop_reason or "cycle limit reached")
    path = tracker.path
    stop = Stop(stop_reason, tracker.s_cmd, cycles[-1].tcp_mm, tracker.s_far, path.position(tracker.s_far),
                tracker.lost_at if tracker.stopping_at is not None else None, tracker.decided_at)
    return TrackRun(cfg, cycles, stop, he, cam_true, sensor.centre_px if sensor else (np.nan, np.nan),
                    {"seed_px": seed_px, "path_knots": (np.array(path.s), np.array(path.p)),
                     "gaps_bridged": tracker.gaps, "start_s": start_s, "taught_mm": taught, "travel": travel})


def sensor_range(cfg: TrackConfig) -> tuple[float, float]:
    """The depths (mm) the seam sensor searches: the camera distance -80 / +120 mm."""
    return cfg.camera_distance_mm - 80.0, cfg.camera_distance_mm + 120.0


def window_length_mm(rig: Rig, cfg: TrackConfig) -> float:
    """The length of seam the sensor window's ``roi_rows`` span at the camera distance, mm."""
    cam = rig.camera
    return cfg.roi_rows * cam.pixel_pitch_mm[1] * cfg.camera_distance_mm / cam.focal_length_mm


def replay(run: TrackRun, rig: Rig) -> ReplayCell:
    """Run a fresh controller and sensor on a recorded run's frames and flange poses (what a recording
    holds: no simulation), with the run's configuration, hand-eye transform, teach point and seed, and
    ``rig`` as the sensor's rig; returns the replay cell, whose ``mismatches`` lists the cycles where the
    command differs from the recorded one (none: the controller is deterministic)."""
    return replay_cell(run.config, run.handeye.cam2flange, run.extras["taught_mm"], run.extras["travel"],
                       run.extras["seed_px"], [Frame(c.t_s, c.flange2base, c.image) for c in run.cycles],
                       [c.tool2base for c in run.cycles], [c.fault for c in run.cycles], rig)


def replay_cell(cfg: TrackConfig, cam2flange: np.ndarray, taught_mm, travel, seed_px, frames: list[Frame],
                commands: list[np.ndarray], faults: list[str], rig: Rig) -> ReplayCell:
    """:func:`replay` from its parts (e.g. read from a recording, :mod:`psvs.robot.recording`): seed_px None
    finds the seed on the first frame as the live run did."""
    near, far = sensor_range(cfg)
    roi, _ = roi_rig(rig, cfg.roi_rows, span_mm=(near, far))
    cell = ReplayCell(frames, commands, faults)
    tracker = SeamTracker(cfg, cam2flange, np.asarray(taught_mm, float), np.asarray(travel, float),
                          window_length_mm(rig, cfg))
    control_loop(cell, tracker, roi, near, far, seed_px, len(frames))
    return cell
