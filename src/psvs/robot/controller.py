"""The seam-tracking controller: seam measurements and flange poses in, torch pose commands out.

Pure: no rendering, no clock, no printing, no arm. Each control cycle it gets an :class:`Observation`
(the cycle's time, the flange pose when the frame was taken, and the seam sensor's measurement of that
frame in the PSVS frame C) and returns a :class:`Command` (the torch pose to reach by the next cycle, and
what it decided). A cell (psvs.robot.cells) reads the arm and the camera, runs the sensor, and carries the
command out: in simulation, on a recording, or on a real arm.

Every cycle: the groove edges go to the base frame through the flange pose and the *calibrated* hand-eye
transform; the fitted groove root extends the seam path model; the torch's progress along the model
advances at the set speed (limited so that it can always stop before the end of what has been seen, plus
the bridge), and the torch pose there (stand-off above the seam, vertical, aimed along the seam ahead) is
the command.

Losing the seam (gap, occlusion, end of the work): the model carries on along its end tangent; if the
seam is seen again within ``bridge_mm`` of its last point the gap is bridged by the spline; once the whole
sensor window is beyond that, the torch is brought to a smooth stop at the last seam point seen, and where
is reported. If the arm refuses a command (:meth:`SeamTracker.fault`), the torch stops where it is.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs.robot.mounting import tool_pose
from psvs.robot.seam import SeamObservation, fit_seam_point
from psvs.robot.seam_model import SeamPath
from psvs.transforms import concat, transform_points

UP = np.array([0.0, 0.0, 1.0])
#: How fast the torch may turn about its axis to keep the PSVS on the seam ahead (a seam of radius
#: 100 mm at 10 mm/s needs 0.1 rad/s), and how fast that rate may change.
MAX_YAW_RATE_RAD_S = 0.3
MAX_YAW_ACCEL_RAD_S2 = 0.5
#: Slack on a measured gap before it counts as longer than the bridge (edge rows lost at the groove's ends).
GAP_TOL_MM = 1.5
#: mm: how far short of the arc's start a held torch waits (SeamTracker.hold_arc).
ARC_HOLD_MM = 0.5


@dataclass(frozen=True)
class TrackConfig:
    """A tracking job: what the controller and its sensor need, on any cell. Speeds mm/s, lengths mm,
    rates Hz. (How a simulated cell renders is :class:`psvs.robot.cells.SimulationConfig`.)

    speed_mm_s : travel speed.            rate_hz : control (and camera) rate.
    standoff_mm : torch tip above the seam root, along the torch axis.
    look_ahead_mm : where the PSVS looks ahead of the torch.  camera_distance_mm : PSVS to the work.
    roi_rows : sensor window rows (paired).  groove_depth_mm : root below the groove edges (joint drawing).
    bridge_mm : longest seam gap bridged.  accel_mm_s2 : travel acceleration / deceleration.
    weld_length_mm : stop after this much welding (None: to the end of the seam).
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
        if self.weld_length_mm is not None and not (math.isfinite(self.weld_length_mm) and self.weld_length_mm > 0):
            raise ValueError(f"weld_length_mm must be a number > 0, got {self.weld_length_mm!r}")
        if self.bridge_mm < 0 or self.bridge_mm >= self.look_ahead_mm:
            raise ValueError(f"bridge_mm must be in [0, look_ahead_mm), got {self.bridge_mm!r}")

    @property
    def arc_on_mm(self) -> float:
        """Progress at which the arc is struck: the run-in until then fills the look-ahead."""
        return self.look_ahead_mm + 10.0


@dataclass(frozen=True, eq=False)
class TrackerSummary:
    """Where a run stands (the controller's state as a record, base frame, mm).

    s_mm, speed_mm_s : the torch's commanded progress along the path model and its speed (mm/s).
    s_far_mm : the furthest seam arc length seen; last_seen_mm (3,) the seam's point there.
    lost_at_s_mm : the torch's progress when the seam was last lost (None: it is seen).
    decided_at_s_mm : the torch's progress when a stop was decided (None: none).
    stopping_at_s_mm : where the torch is to stop (None: no stop decided); stop_reason : why ('' none).
    gaps_bridged : (from, to) seam arc lengths of the gaps bridged, mm.
    path_knots : (s (K,), points (K, 3)) of the path model, mm.
    arc_blocked : a halt came before the arc was struck: it never is, however far the torch brakes.
    """

    s_mm: float
    speed_mm_s: float
    s_far_mm: float
    last_seen_mm: np.ndarray
    lost_at_s_mm: float | None
    decided_at_s_mm: float | None
    stopping_at_s_mm: float | None
    stop_reason: str
    gaps_bridged: tuple[tuple[float, float], ...]
    path_knots: tuple[np.ndarray, np.ndarray]
    arc_blocked: bool = False


@dataclass(frozen=True, eq=False)
class Observation:
    """One cycle's input: time (s), the flange pose flange2base (4, 4) mm when the frame was taken, and
    the seam sensor's measurement of that frame (frame C)."""

    t_s: float
    flange2base: np.ndarray
    seam: SeamObservation


@dataclass(frozen=True, eq=False)
class Command:
    """One cycle's output (base frame, mm).

    tool2base : (4, 4) the torch pose to reach by the next cycle.  s_mm, speed_mm_s : progress on the model.
    seam_mm : (3,) the seam root seen (NaN if none).  points_mm : (N, 3) the groove-edge points seen.
    valid : the frame's seam point was usable; reason : why not ('' when valid).
    accepted : it extended the path model (the sensor tracks from it).  stopping : a stop is decided.
    path_mm : (M, 3) the path model from the torch to the last seam point.
    """

    t_s: float
    tool2base: np.ndarray
    s_mm: float
    speed_mm_s: float
    seam_mm: np.ndarray
    points_mm: np.ndarray
    valid: bool
    reason: str
    accepted: bool
    stopping: bool
    path_mm: np.ndarray

    @property
    def target_mm(self) -> np.ndarray:
        """(3,) the torch tip commanded."""
        return self.tool2base[:3, 3]


class SeamTracker:
    """The controller of one run (state: the path model, the progress and speed, the heading, what was
    seen and lost). See the module docstring.

    Parameters
    ----------
    cfg : TrackConfig
    cam2flange : (4, 4) the calibrated hand-eye transform, mm.
    taught_mm : (3,) the taught start on the seam (base frame); travel : (3,) the taught direction.
    window_mm : the length of seam the sensor window spans (the stop decision waits until the whole window
        is past the last seam point plus the bridge).
    """

    def __init__(self, cfg: TrackConfig, cam2flange: np.ndarray, taught_mm, travel, window_mm: float):
        self.cfg, self.cam2flange, self.window_mm = cfg, np.asarray(cam2flange, float), float(window_mm)
        taught, travel = np.asarray(taught_mm, float), np.asarray(travel, float)
        self.path = SeamPath(taught, travel)
        self.s_cmd, self.v, self.width = 0.0, 0.0, None
        self.yaw, self.yaw_rate = math.atan2(travel[1], travel[0]), 0.0   # the heading, turned smoothly
        self.s_far, self.gaps = 0.0, []     # furthest seam arc length seen; gaps bridged (from, to) mm
        self.end_seen = taught              # the seam's point there (base frame, mm)
        self.decided_at, self.stopping_at, self.lost_at, self.stop_reason = None, None, None, ""
        self.arc_held = False               # the torch waits short of the arc's start (hold_arc)
        self.arc_blocked = False            # halted before the arc was struck: it never is

    @property
    def arc_struck(self) -> bool:
        """The torch has come to where the arc is struck (:attr:`TrackConfig.arc_on_mm`): the run-in is over."""
        return self.s_cmd >= self.cfg.arc_on_mm

    def hold_arc(self, hold: bool) -> None:
        """Whether the torch must wait :data:`ARC_HOLD_MM` short of the arc's start (braking at the job's
        deceleration to rest there, tracking on), e.g. until a check of the calibration has judged; released, it
        goes on. No effect once the arc is struck."""
        self.arc_held = bool(hold) and not self.arc_struck

    @property
    def stopped(self) -> bool:
        """A stop is decided and the commanded speed is zero."""
        return self.stopping_at is not None and self.v == 0.0

    def step(self, obs: Observation) -> Command:
        """One control cycle: from the observation (the flange pose and what the seam sensor saw) the next
        tool pose to command (:class:`Command`)."""
        cfg = self.cfg
        dt = 1.0 / cfg.rate_hz
        cam2base = concat(self.cam2flange, obs.flange2base)
        pts, seam, reason = np.empty((0, 3)), np.full(3, np.nan), obs.seam.reason
        if obs.seam.valid:
            a, b = (transform_points(cam2base, e) for e in obs.seam.edges_mm)
            pts = np.vstack([a, b])
            sp = fit_seam_point(a, b, cfg.groove_depth_mm, UP)
            seam = sp.point_mm
            reason, accepted = self._extend(sp, a, b)
        else:
            accepted = False
        if accepted:
            self.lost_at = None
        elif self.lost_at is None and (not obs.seam.valid or reason):
            self.lost_at = self.s_cmd
        self._decide_stop()
        self._advance(dt)
        tool = self._aim(dt)
        ahead = np.array([self.path.position(s) for s in np.linspace(self.s_cmd, max(self.s_cmd, self.path.s_end), 20)])
        return Command(t_s=obs.t_s, tool2base=tool, s_mm=self.s_cmd, speed_mm_s=self.v, seam_mm=seam, points_mm=pts,
                       valid=bool(obs.seam.valid and not reason), reason=reason, accepted=bool(accepted),
                       stopping=self.stopping_at is not None, path_mm=ahead)

    def summary(self) -> TrackerSummary:
        """The run's state as a record (see :class:`TrackerSummary`)."""
        return TrackerSummary(
            s_mm=self.s_cmd, speed_mm_s=self.v, s_far_mm=self.s_far,
            last_seen_mm=self.path.position(self.s_far), lost_at_s_mm=self.lost_at,
            decided_at_s_mm=self.decided_at, stopping_at_s_mm=self.stopping_at, stop_reason=self.stop_reason,
            gaps_bridged=tuple(self.gaps), path_knots=(np.array(self.path.s), np.array(self.path.p)),
            arc_blocked=self.arc_blocked)

    def fault(self, reason: str) -> None:
        """The arm could not carry out the last command (unreachable, a joint limit): stop where the torch
        is, with the arm's reason."""
        if self.stopping_at is None:
            self.stopping_at, self.stop_reason = self.s_cmd, f"arm: {reason}"
        self.v = 0.0

    def halt(self, reason: str) -> None:
        """Stop safely, told from outside the seam (e.g. the calibration has drifted): brake from here at the
        job's deceleration, tracking on meanwhile, and weld no further than where the torch comes to rest; before
        the arc is struck, it never is."""
        if self.stopping_at is None and not self.arc_struck:
            self.arc_blocked = True
        if self.stopping_at is None:
            self.stopping_at = self.s_cmd + self.v ** 2 / (2 * self.cfg.accel_mm_s2)
            self.stop_reason = reason

    def _extend(self, sp, a, b) -> tuple[str, bool]:
        """Try the frame's seam point on the path model: ('' when it is usable, else why not; whether it
        extended the model)."""
        cfg, path = self.cfg, self.path
        seam = sp.point_mm
        t_end = path.tangent(path.s_end)
        tangent = sp.tangent if sp.tangent @ t_end >= 0 else -sp.tangent
        self.width = self.width or sp.width_mm    # the groove's width, taught by the first frame
        reason = _off_model(path, seam, t_end)
        if abs(sp.width_mm - self.width) > 0.2 * self.width:
            reason = f"groove incomplete (width {sp.width_mm:.1f} mm, taught {self.width:.1f} mm)"
        if reason:
            return reason, False
        # the stretch of seam this frame saw, as arc lengths on the model: where the centre line starts and
        # ends, halfway between the two edges' ends (a groove end may cross obliquely)
        top = seam + cfg.groove_depth_mm * UP
        ea, eb = (a - top) @ tangent, (b - top) @ tangent
        along = np.array([(ea.min() + eb.min()) / 2, (ea.max() + eb.max()) / 2])
        s_here = path.arc_of(seam, tangent)
        # a gap: the straight distance from the end of the seam seen before to where it shows again (a
        # chord: under 0.01 mm from the arc over a bridge on a seam of R >= 100 mm; the model's arc lengths
        # across the gap follow its extrapolation, whose end tangent is least sure)
        gap = 0.0
        if self.lost_at is not None and s_here + along.min() > self.s_far:
            gap = float(np.linalg.norm(seam + along.min() * tangent - self.end_seen))
        if gap > cfg.bridge_mm + GAP_TOL_MM:
            if self.stopping_at is None:
                self.stopping_at = self.s_far
                # a gap or frames the sensor could not read: from here neither tells the two apart
                self.stop_reason = (f"no seam seen over {gap:.1f} mm after s = {self.s_far:.1f} mm (a gap in the "
                                    f"seam, or frames the sensor could not read), longer than the {cfg.bridge_mm:g} "
                                    "mm bridge")
            return "beyond a gap too long to bridge", False
        if gap > GAP_TOL_MM:      # shorter: a frame or two lost, within the measuring slack
            self.gaps.append((self.s_far, self.s_far + gap))
        accepted = path.add(seam, tangent)
        if accepted and path.s_end + float(along.max()) > self.s_far:
            self.s_far = path.s_end + float(along.max())
            self.end_seen = seam + float(along.max()) * tangent
        return "", accepted

    def _decide_stop(self) -> None:
        cfg = self.cfg
        if self.stopping_at is None and self.lost_at is not None and \
                self.s_cmd + cfg.look_ahead_mm - self.window_mm > self.s_far + cfg.bridge_mm:
            # the whole window is past the bridge and has seen no seam: weld to the last seam point seen
            self.stopping_at = self.s_far
            self.stop_reason = (f"seam lost: nothing seen for {cfg.bridge_mm:g} mm after s = {self.s_far:.1f} "
                                f"mm (gap longer than the bridge, or the end of the seam)")

    def _advance(self, dt: float) -> None:
        cfg = self.cfg
        s_limit = self.path.s_end + cfg.bridge_mm if self.stopping_at is None else self.stopping_at
        if self.arc_held:
            s_limit = min(s_limit, max(cfg.arc_on_mm - ARC_HOLD_MM, self.s_cmd))
        if cfg.weld_length_mm is not None:
            end = cfg.arc_on_mm + cfg.weld_length_mm
            s_limit = min(s_limit, end)
            if self.stopping_at is None and self.s_cmd >= end - 1e-6:
                self.stopping_at, self.stop_reason = end, "weld length reached"
        if self.stopping_at is not None and self.decided_at is None:
            self.decided_at = self.s_cmd
        v_allow = math.sqrt(2 * cfg.accel_mm_s2 * max(0.0, s_limit - self.s_cmd))
        self.v = max(0.0, min(cfg.speed_mm_s, self.v + cfg.accel_mm_s2 * dt, v_allow))
        self.s_cmd = min(self.s_cmd + self.v * dt, s_limit)

    def _aim(self, dt: float) -> np.ndarray:
        path, s = self.path, self.s_cmd
        path.fit(s)
        target = path.position(s) + self.cfg.standoff_mm * UP
        aim = path.position(s + self.cfg.look_ahead_mm) - path.position(s)
        self.yaw, self.yaw_rate = _steer(self.yaw, self.yaw_rate,
                                         aim if np.hypot(aim[0], aim[1]) > 1.0 else path.tangent(s), dt)
        return tool_pose(target, np.array([math.cos(self.yaw), math.sin(self.yaw), 0.0]))


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
