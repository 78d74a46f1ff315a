"""Closed-loop seam tracking in simulated time: render -> sensor -> path model -> torch command -> servo.

Every control cycle (1 / rate_hz of simulated time): the complex image (the ROI rows) is rendered from the
camera pose the arm's joints really give; the sensor matches both groove edges with their twins and
triangulates them (frame C); they go to the base frame through the arm's kinematics and the *calibrated*
hand-eye transform; the fitted groove root extends the seam path model; the torch's progress along the
model advances at the set speed (limited so that it can always stop before the end of what has been seen,
plus the bridge), and the torch pose there (stand-off above the seam, vertical, aimed along the seam)
goes through inverse kinematics to the joint servo. Wall time of each stage is measured.

Losing the seam (gap, occlusion, end of the work): the model carries on along its end tangent; if the
seam is seen again within ``bridge_mm`` of its last point the gap is bridged by the spline; once the whole
sensor window is beyond that, the torch is brought to a smooth stop at the last seam point seen, and where
is reported.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from psvs.optics.rig import Rig
from psvs.robot.arm import Arm, ArmLimits
from psvs.robot.cell import MOUNT_ERROR, cam2tool, tool2flange, tool_pose, transform
from psvs.robot.handeye import HandEyeResult, calibrate_from_views
from psvs.robot.seam_model import SeamPath
from psvs.robot.sensor import SeamSensor, auto_seed, fit_seam_point, roi_rig
from psvs.robot.workpiece import Workpiece
from psvs.simulate.render import render
from psvs.simulate.scene import Lighting, Pose, Scene, SceneObject
from psvs.simulate.sensor import Sensor
from psvs.simulate.sequence import scene_in_rig_frame
from psvs.simulate.textures import CircleGrid

#: A PUMA 560 configuration (right arm, elbow up) with the torch down over the table; IK starts here.
HOME_Q = np.radians([23.0, 4.5, -168.0, -54.0, -53.0, 161.0])
UP = np.array([0.0, 0.0, 1.0])
#: The largest joint change one control cycle may ask for (a path step of < 1 mm moves no joint by
#: more than ~0.01 rad here): more means the solver switched arm configuration.
MAX_IK_STEP_RAD = 0.1
#: How fast the torch may turn about its axis to keep the PSVS on the seam ahead (a seam of radius
#: 100 mm at 10 mm/s needs 0.1 rad/s), and how fast that rate may change.
MAX_YAW_RATE_RAD_S = 0.3
MAX_YAW_ACCEL_RAD_S2 = 0.5
#: Slack on a measured gap before it counts as longer than the bridge (edge rows lost at the groove's ends).
GAP_TOL_MM = 1.5


@dataclass(frozen=True)
class TrackConfig:
    """A tracking job. Speeds mm/s, lengths mm, rates Hz.

    speed_mm_s : travel speed.            rate_hz : control (and camera) rate.
    standoff_mm : torch tip above the seam root, along the torch axis.
    look_ahead_mm : where the PSVS looks ahead of the torch.  camera_distance_mm : PSVS to the work.
    roi_rows : sensor window rows.         groove_depth_mm : root below the groove edges (joint drawing).
    bridge_mm : longest seam gap bridged.  accel_mm_s2 : travel acceleration / deceleration.
    weld_length_mm : stop after this much welding (None: to the end of the seam).
    start_offset_mm : the taught start, this far along the seam from the workpiece's end.
    supersample : render anti-aliasing.    noise_seed : sensor noise seed.
    """

    speed_mm_s: float = 10.0
    rate_hz: float = 25.0
    standoff_mm: float = 15.0
    look_ahead_mm: float = 40.0
    camera_distance_mm: float = 300.0
    roi_rows: int = 32
    groove_depth_mm: float = 3.0
    bridge_mm: float = 10.0
    accel_mm_s2: float = 25.0
    weld_length_mm: float | None = None
    start_offset_mm: float = 50.0
    supersample: int = 2
    noise_seed: int = 0

    def __post_init__(self):
        for name in ("speed_mm_s", "rate_hz", "standoff_mm", "look_ahead_mm", "camera_distance_mm",
                     "accel_mm_s2"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a number > 0, got {v!r}")
        if self.speed_mm_s > 100:
            raise ValueError(f"speed_mm_s must be <= 100 mm/s (a seam-tracking speed), got {self.speed_mm_s!r}")
        if not 1 <= self.rate_hz <= 250:
            raise ValueError(f"rate_hz must be in 1..250 Hz, got {self.rate_hz!r}")
        if not isinstance(self.roi_rows, int) or self.roi_rows < 8:
            raise ValueError(f"roi_rows must be an integer >= 8, got {self.roi_rows!r}")
        if self.weld_length_mm is not None and not self.weld_length_mm > 0:
            raise ValueError(f"weld_length_mm must be > 0, got {self.weld_length_mm!r}")
        if self.bridge_mm < 0 or self.bridge_mm >= self.look_ahead_mm:
            raise ValueError(f"bridge_mm must be in [0, look_ahead_mm), got {self.bridge_mm!r}")

    @property
    def arc_on_mm(self) -> float:
        """Progress at which the arc is struck: the run-in until then fills the look-ahead."""
        return self.look_ahead_mm + 10.0


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
    image: np.ndarray           # (roi_rows, W) uint8
    points_mm: np.ndarray       # (N, 3) edge points seen, base frame
    path_mm: np.ndarray         # (M, 3) path model ahead of the torch
    wall_render_s: float
    wall_sensor_s: float
    wall_control_s: float


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


def calibrate_cell(rig: Rig, cfg: TrackConfig, arm: Arm, views: int = 12,
                   true_rig: Rig | None = None) -> tuple[HandEyeResult, np.ndarray]:
    """Hand-eye calibration session: a 4 x 5 circle grid on the table, shown to the PSVS from ``views``
    flange poses (tilted up to ~12 deg, turned about the vertical); returns the result and the true
    cam2flange of the simulated hardware. The views are rendered through ``true_rig`` (default ``rig``),
    the rig as built, and calibrated with ``rig``, what the sensor knows of it."""
    grid = CircleGrid(rows=4, cols=5, spacing_mm=15.0, diameter_mm=7.0)
    target2base = transform(np.diag([1.0, -1.0, -1.0]), (550.0, 0.0, 0.0))  # lying face up on the table
    plate = SceneObject("rectangle", Pose(target2base[:3, :3], target2base[:3, 3]), grid, size_mm=(320.0, 320.0),
                        name="target")
    scene = Scene((plate,), cell_lighting(cfg), None)
    nominal = tool2flange() @ cam2tool(cfg.look_ahead_mm, cfg.standoff_mm, cfg.camera_distance_mm)
    true = nominal @ MOUNT_ERROR
    rng = np.random.default_rng(7)
    from scipy.spatial.transform import Rotation
    images, flanges = [], []
    for k in range(views):
        yaw = np.pi / 2 + (k - (views - 1) / 2) * 0.05
        tilt = Rotation.from_rotvec(np.append(rng.uniform(-0.35, 0.35, 2), yaw)).as_matrix()
        cam_R = tilt @ np.diag([1.0, -1.0, -1.0])   # camera looking down, turned and tilted
        cam_pos = target2base[:3, 3] - cfg.camera_distance_mm * cam_R[:, 2] + np.append(rng.uniform(-10, 10, 2), 0)
        cam2base = transform(cam_R, cam_pos)
        flange = cam2base @ np.linalg.inv(nominal)
        q = arm.ikine(flange, HOME_Q)
        F = arm.fkine(q)
        img = render(scene_in_rig_frame(scene, np.linalg.inv(F @ true)), true_rig or rig, supersample=1,
                     seed=100 + k).image
        images.append(img)
        flanges.append(F)
    return calibrate_from_views(images, flanges, rig, grid, nominal, target2base), true


def track(workpiece: Workpiece, rig: Rig, cfg: TrackConfig = TrackConfig(), seed_px=None,
          limits: ArmLimits = ArmLimits(), handeye: tuple[HandEyeResult, np.ndarray] | None = None,
          progress=None, true_rig: Rig | None = None) -> TrackRun:
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
    """
    dt = 1.0 / cfg.rate_hz
    arm = Arm(HOME_Q, limits)
    he, cam_true = handeye if handeye is not None else calibrate_cell(rig, cfg, arm, true_rig=true_rig)
    X = he.cam2flange
    T_tool = tool2flange()
    roi, v0 = roi_rig(rig, cfg.roi_rows)
    roi_true = roi if true_rig is None else roi_rig(true_rig, cfg.roi_rows, v0)[0]   # the same sensor rows
    # the operator jogs the torch to the seam's start (a teach point, 0.3 mm off the seam) and teaches the
    # direction of travel: the only use of the true seam in the loop (scoring aside)
    x0 = workpiece.x_range_mm[0] + cfg.start_offset_mm
    p0, p1 = workpiece.seam_base([x0, x0 + 1.0])
    travel = (p1 - p0) / np.linalg.norm(p1 - p0)
    taught = p0 + 0.3 * np.cross(UP, travel)
    path = SeamPath(taught, travel)
    tool0 = tool_pose(taught + cfg.standoff_mm * UP, travel)
    arm.q = arm.ikine(tool0 @ np.linalg.inv(T_tool), HOME_Q)
    near, far = cfg.camera_distance_mm - 80.0, cfg.camera_distance_mm + 120.0
    # the length of seam the sensor window spans: the gap is too long once the whole window is beyond
    # the last seam point + the bridge
    cam = rig.camera
    window_mm = cfg.roi_rows * cam.pixel_pitch_mm[1] * cfg.camera_distance_mm / cam.focal_length_mm
    sensor = None
    s_cmd, v, width = 0.0, 0.0, None
    yaw, yaw_rate = math.atan2(travel[1], travel[0]), 0.0   # the torch's heading, turned smoothly
    s_far, gaps = 0.0, []        # furthest seam arc length seen; gaps bridged (from, to) mm
    decided_at = None
    stopping_at, lost_at, stop_reason = None, None, ""
    cycles: list[Cycle] = []
    max_cycles = int((workpiece.params["length_mm"] + 100) / cfg.speed_mm_s * cfg.rate_hz * 2) + 200
    for k in range(max_cycles):
        F = arm.fkine()
        t0 = time.perf_counter()
        world2cam = np.linalg.inv(F @ cam_true)
        img = render(scene_in_rig_frame(workpiece.scene, world2cam), roi_true, supersample=cfg.supersample,
                     sensor=Sensor(), seed=cfg.noise_seed + k).image
        t1 = time.perf_counter()
        # ---- sensor: groove edges and twins -> frame C -> base (calibrated hand-eye) -> groove root
        if sensor is None:
            seed_px = auto_seed(img) if seed_px is None else tuple(float(c) for c in seed_px)
            sensor = SeamSensor(roi, seed_px, near, far)
        obs = sensor.measure(img)
        cam2base = F @ X
        pts = np.empty((0, 3))
        seam = np.full(3, np.nan)
        reason = obs.reason
        if obs.valid:
            a, b = (e @ cam2base[:3, :3].T + cam2base[:3, 3] for e in obs.edges_mm)
            pts = np.vstack([a, b])
            sp = fit_seam_point(a, b, cfg.groove_depth_mm, UP)
            seam = sp.point_mm
        t2 = time.perf_counter()
        # ---- path model and control
        accepted = False
        if obs.valid:
            t_end = path.tangent(path.s_end)
            tangent = sp.tangent if sp.tangent @ t_end >= 0 else -sp.tangent
            width = width or sp.width_mm    # the groove's width, taught by the first frame
            reason = _off_model(path, seam, t_end)
            if abs(sp.width_mm - width) > 0.2 * width:
                reason = f"groove incomplete (width {sp.width_mm:.1f} mm, taught {width:.1f} mm)"
            if not reason:
                # the stretch of seam this frame saw, as arc lengths on the model: where the centre line
                # starts and ends, halfway between the two edges' ends (a groove end may cross obliquely)
                top = seam + cfg.groove_depth_mm * UP
                ea, eb = (a - top) @ tangent, (b - top) @ tangent
                along = np.array([(ea.min() + eb.min()) / 2, (ea.max() + eb.max()) / 2])
                s_here = path.arc_of(seam, tangent)
                if lost_at is not None and s_here + along.min() - s_far > cfg.bridge_mm + GAP_TOL_MM:
                    if stopping_at is None:
                        stopping_at = s_far
                        stop_reason = (f"seam gap of {s_here + along.min() - s_far:.1f} mm after s = "
                                       f"{s_far:.1f} mm, longer than the {cfg.bridge_mm:g} mm bridge")
                    reason = "beyond a gap too long to bridge"
                else:
                    if lost_at is not None and s_here + along.min() > s_far:
                        gaps.append((s_far, s_here + float(along.min())))
                    accepted = path.add(seam, tangent)
                    if accepted:
                        s_far = max(s_far, path.s_end + float(along.max()))
        if accepted or (obs.valid and not reason and sensor.half_width_px is None):
            sensor.commit(obs)
        if accepted:
            lost_at = None
        elif lost_at is None and (not obs.valid or reason):
            lost_at = s_cmd
        if stopping_at is None and lost_at is not None and \
                s_cmd + cfg.look_ahead_mm - window_mm > s_far + cfg.bridge_mm:
            # the whole window is past the bridge and has seen no seam: weld to the last seam point seen
            stopping_at = s_far
            stop_reason = (f"seam lost: nothing seen for {cfg.bridge_mm:g} mm after s = {s_far:.1f} mm "
                           f"(gap longer than the bridge, or the end of the seam)")
        s_limit = path.s_end + cfg.bridge_mm if stopping_at is None else stopping_at
        if cfg.weld_length_mm is not None:
            end = cfg.arc_on_mm + cfg.weld_length_mm
            s_limit = min(s_limit, end)
            if stopping_at is None and s_cmd >= end - 1e-6:
                stopping_at, stop_reason = end, "weld length reached"
        if stopping_at is not None and decided_at is None:
            decided_at = s_cmd
        v_allow = math.sqrt(2 * cfg.accel_mm_s2 * max(0.0, s_limit - s_cmd))
        v = max(0.0, min(cfg.speed_mm_s, v + cfg.accel_mm_s2 * dt, v_allow))
        s_cmd = min(s_cmd + v * dt, s_limit)
        path.fit(s_cmd)
        target = path.position(s_cmd) + cfg.standoff_mm * UP
        aim = path.position(s_cmd + cfg.look_ahead_mm) - path.position(s_cmd)
        yaw, yaw_rate = _steer(yaw, yaw_rate, aim if np.hypot(aim[0], aim[1]) > 1.0 else path.tangent(s_cmd), dt)
        tool = tool_pose(target, np.array([math.cos(yaw), math.sin(yaw), 0.0]))
        try:
            q_t = arm.ikine(tool @ np.linalg.inv(T_tool), max_step_rad=MAX_IK_STEP_RAD)
            step = arm.servo(q_t, dt)
        except ValueError as exc:
            step = arm.stop(dt)
            if stopping_at is None:
                stopping_at, stop_reason = s_cmd, f"arm: {exc}"
            v = 0.0
        t3 = time.perf_counter()
        tcp = (arm.fkine() @ T_tool)[:3, 3]
        ahead = np.array([path.position(s) for s in np.linspace(s_cmd, max(s_cmd, path.s_end), 20)])
        cyc = Cycle(k * dt, s_cmd, v, tcp, target, seam, obs.valid and not reason, reason, step.q, step.qd,
                    step.qdd_peak, img, pts, ahead, t1 - t0, t2 - t1, t3 - t2)
        cycles.append(cyc)
        if progress is not None:
            progress(cyc)
        if stopping_at is not None and v == 0.0 and np.max(np.abs(arm.qd)) < 1e-6:
            break
    else:
        stop_reason = stop_reason or "cycle limit reached"
    stop = Stop(stop_reason, s_cmd, cycles[-1].tcp_mm, s_far, path.position(s_far),
                lost_at if stopping_at is not None else None, decided_at)
    return TrackRun(cfg, cycles, stop, he, cam_true, sensor.centre_px if sensor else (np.nan, np.nan),
                    {"seed_px": seed_px, "path_knots": (np.array(path.s), np.array(path.p)), "gaps_bridged": gaps})


def _steer(yaw: float, yaw_rate: float, wanted: np.ndarray, dt: float) -> tuple[float, float]:
    """The torch's heading (rad) and its rate (rad/s) one cycle on, turning toward the horizontal
    direction ``wanted``: a first-order approach (0.5 s) with the rate and its change bounded, so that the
    wrist, which a bent-neck torch needs for turning about its own axis, is never pushed to its limits."""
    err = (math.atan2(wanted[1], wanted[0]) - yaw + math.pi) % (2 * math.pi) - math.pi
    want_rate = float(np.clip(err / 0.5, -MAX_YAW_RATE_RAD_S, MAX_YAW_RATE_RAD_S))
    yaw_rate += float(np.clip(want_rate - yaw_rate, -MAX_YAW_ACCEL_RAD_S2 * dt, MAX_YAW_ACCEL_RAD_S2 * dt))
    return yaw + yaw_rate * dt, yaw_rate


def _off_model(path: SeamPath, point: np.ndarray, t_end: np.ndarray, lateral_mm: float = 2.0,
               vertical_mm: float = 3.0) -> str:
    """'' when the seen seam point continues the path model, else why not (an outlier: spatter, a
    stray edge)."""
    if len(path.s) < 4:
        return ""
    end = path.position(path.s_end)
    d = point - end
    ds = float(d @ t_end)
    pred = path.position(path.s_end + ds)
    e = point - pred
    horiz = np.cross(UP, t_end)
    horiz /= np.linalg.norm(horiz)
    # after a gap the model's straight continuation departs from a curved seam by ds^2 / 2R (R >= 100 mm)
    bend = max(ds, 0.0) ** 2 / (2 * 100.0)
    if abs(e @ horiz) > lateral_mm + bend or abs(e[2]) > vertical_mm + bend:
        return f"seam point {abs(e @ horiz):.1f} mm beside / {abs(e[2]):.1f} mm off the path model"
    return ""
