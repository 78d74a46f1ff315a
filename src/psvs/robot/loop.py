"""Closed-loop seam tracking in the simulated cell: the controller (psvs.robot.controller) run by
:func:`psvs.robot.cells.control_loop` on the simulated PUMA 560 (:class:`psvs.robot.cells.SimulatedCell`):
every control cycle (1 / rate_hz of simulated time) the sensor window is rendered from the camera pose
the arm's joints really give, the seam sensor matches both groove edges with their twins, the controller
turns them into a torch pose, and the arm's IK and servo carry it out. Wall time of each stage is measured.
Also :func:`replay` of a recorded run.

A run is three steps: the operator teaches the start (:func:`teach`), the sensor window is placed from
what the sensor knows of the rig (:func:`sensor_setup`), then the loop runs (:func:`track`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from psvs.health.check import TOLERANCE_PX
from psvs.health.rolling import FIRST_COST_S, SHARE, RollingCheck
from psvs.optics.rig import Rig
from psvs.optics.window import roi_rig
from psvs.robot.arm import Arm
from psvs.robot.cells import CycleResult, Frame, ReplayCell, SimulatedCell, SimulationConfig, control_loop
from psvs.robot.controller import UP, SeamTracker, TrackConfig
from psvs.robot.drift import DriftWatch, HealthNote, RecordedHalts
from psvs.robot.handeye import HandEyeResult
from psvs.robot.handeye_session import calibrate_cell
from psvs.robot.mounting import HOME_Q, tool2flange, tool_pose
from psvs.robot.sensor import SensorSetup
from psvs.robot.workpiece import Workpiece
from psvs.simulate.render import SAMPLE_SECONDS
from psvs.transforms import concat, invert_transform

#: How far the operator's teach point lies beside the true seam, mm (a careful jog, not a perfect one).
TEACH_OFFSET_MM = 0.3
#: Seam the torch travels besides what it welds, mm: the run-in to the arc's start and the stop.
RUN_IN_OUT_MM = 100.0
#: Seconds a control cycle costs besides rendering its window: the seam sensor and the controller (4.5 and
#: 4.7 ms median on the reference host, docs/benchmarks.md), rounded up.
CYCLE_SECONDS = 0.01


def track_cycles(length_mm: float, cfg: TrackConfig) -> int:
    """The control cycles a run welding ``length_mm`` of seam takes: the length and :data:`RUN_IN_OUT_MM`
    at ``cfg.speed_mm_s``, one cycle every 1 / ``cfg.rate_hz`` s."""
    return int((length_mm + RUN_IN_OUT_MM) / cfg.speed_mm_s * cfg.rate_hz)


def cycle_seconds(rig: Rig, cfg: TrackConfig, sim: SimulationConfig = SimulationConfig()) -> float:
    """Estimated wall time of one simulated control cycle, s: rendering the sensor window (``cfg.roi_rows``
    rows of the camera at ``sim.supersample``; :data:`psvs.simulate.render.SAMPLE_SECONDS` a sample) and
    :data:`CYCLE_SECONDS` of sensing and control."""
    w = rig.camera.image_size_px[0]
    return w * cfg.roi_rows * sim.supersample ** 2 * SAMPLE_SECONDS + CYCLE_SECONDS


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
    health: HealthNote | None = None   # the rolling self-check as of this cycle (None: not run)


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
    arc_blocked: bool = False             # halted before the arc was struck: it never was


@dataclass(frozen=True, eq=False)
class Teach:
    """What the operator teaches before the run: a point on the seam's start (3,) mm and the direction
    of travel there (3,) unit, base frame."""

    taught_mm: np.ndarray
    travel: np.ndarray


@dataclass(frozen=True, eq=False)
class TrackRun:
    """A finished run: its settings, every cycle, the stop, the hand-eye calibration used and the true
    mounting (scoring), the teach, the seed pixel used (u, v) px, the path model's knots (s (K,), points
    (K, 3)) mm, the gaps bridged ((from, to) arc lengths, mm) and the set-up time before the first cycle
    (s, the hand-eye session included when it ran) and the rolling self-check's summary (None: not run)."""

    config: TrackConfig
    simulation: SimulationConfig
    cycles: list[Cycle]
    stop: Stop
    handeye: HandEyeResult
    cam2flange_true: np.ndarray
    teach: Teach
    seed_px: tuple[float, float] | None
    path_knots: tuple[np.ndarray, np.ndarray]
    gaps_bridged: tuple[tuple[float, float], ...]
    start_s: float
    health: dict | None = None     # the rolling self-check's summary (DriftWatch.summary; None: not run)


class TrackListener(Protocol):
    """Who watches a run (e.g. a recorder): told the start, then every cycle; one with a ``watch``
    (:class:`Watching`) also checks the calibration as the run goes."""

    def started(self, cam2flange: np.ndarray, teach: Teach) -> None:
        """Called once before the first cycle, with the mount and the taught start."""

    def cycle(self, cycle: Cycle) -> None:
        """Called after every control cycle with its record."""


class Watching:
    """A listener that rides the rolling self-check ``watch`` (a DriftWatch, :func:`drift_watch`) along a run,
    passing the start and the cycles on to ``listener`` (None: nobody else)."""

    def __init__(self, watch: DriftWatch, listener: TrackListener | None = None):
        self.watch, self.listener = watch, listener

    def started(self, cam2flange: np.ndarray, teach: Teach) -> None:
        """Passed on."""
        if self.listener is not None:
            self.listener.started(cam2flange, teach)

    def cycle(self, cycle: Cycle) -> None:
        """Passed on."""
        if self.listener is not None:
            self.listener.cycle(cycle)


def teach(workpiece: Workpiece, cfg: TrackConfig, sim: SimulationConfig, arm: Arm) -> Teach:
    """The operator jogs the torch to the seam's start (``sim.start_offset_mm`` along it, a teach point
    :data:`TEACH_OFFSET_MM` beside it) at the stand-off and teaches the direction of travel: the only use
    of the true seam in the loop (scoring aside). Moves ``arm`` there."""
    x0 = workpiece.x_range_mm[0] + sim.start_offset_mm
    p0, p1 = workpiece.seam_base([x0, x0 + 1.0])
    travel = (p1 - p0) / np.linalg.norm(p1 - p0)
    taught = p0 + TEACH_OFFSET_MM * np.cross(UP, travel)
    tool2base = tool_pose(taught + cfg.standoff_mm * UP, travel)
    arm.q = arm.ikine(concat(invert_transform(tool2flange()), tool2base), HOME_Q)
    return Teach(taught, travel)


def sensor_range(cfg: TrackConfig) -> tuple[float, float]:
    """The depths (mm) the seam sensor searches: the camera distance -80 / +120 mm."""
    return cfg.camera_distance_mm - 80.0, cfg.camera_distance_mm + 120.0


def window_length_mm(rig: Rig, cfg: TrackConfig) -> float:
    """The length of seam the sensor window's ``roi_rows`` span at the camera distance, mm."""
    cam = rig.camera
    return cfg.roi_rows * cam.pixel_pitch_mm[1] * cfg.camera_distance_mm / cam.focal_length_mm


def sensor_setup(rig: Rig, cfg: TrackConfig, seed_px=None) -> tuple[SensorSetup, int]:
    """The seam sensor's set-up from what it knows of the rig: its window (``cfg.roi_rows`` rows, taller
    on a build by the twins' row offset over the sensor's depth range, :func:`psvs.optics.window.roi_rig`)
    and its first row v0 in the full image."""
    near, far = sensor_range(cfg)
    roi, v0 = roi_rig(rig, cfg.roi_rows, span_mm=(near, far))
    return SensorSetup(roi, near, far, None if seed_px is None else tuple(float(c) for c in seed_px)), v0


def check_frames_expected(cycles: int, share: float = SHARE) -> int:
    """The whole frames a run of ``cycles`` control cycles is expected to hand its rolling self-check (each
    rendered in simulation; for the run's time budget): its credit, ``share`` of :data:`CYCLE_SECONDS` of
    sensing a cycle, covering steps of :data:`psvs.health.rolling.FIRST_COST_S`; at most one a cycle."""
    return min(cycles, 1 + int(cycles * share * CYCLE_SECONDS / FIRST_COST_S))


def drift_watch(rig: Rig, cfg: TrackConfig, tolerance_px: float = TOLERANCE_PX, stop_on_drift: bool = False,
                share: float = SHARE) -> DriftWatch:
    """The rolling self-check of a run tracking with ``rig`` (what the sensor was calibrated to) over the seam
    sensor's depths (:func:`sensor_range`), at ``share`` of the sensor's time (psvs.robot.drift)."""
    return DriftWatch(RollingCheck(rig, *sensor_range(cfg), tolerance_px, share), stop_on_drift)


def _cycle(res: CycleResult, tcp_mm: np.ndarray) -> Cycle:
    """The record of one cycle of the simulated cell (its servo step always present); an arm fault stops
    the torch (the controller's speed drops to 0 at once)."""
    c, step = res.command, res.step
    return Cycle(t_s=res.frame.t_s, s_mm=c.s_mm, speed_mm_s=0.0 if res.fault else c.speed_mm_s, tcp_mm=tcp_mm,
                 target_mm=c.target_mm, seam_mm=c.seam_mm, valid=c.valid, reason=c.reason, q=step.q, qd=step.qd,
                 qdd_peak=step.qdd_peak, image=res.frame.image, points_mm=c.points_mm, path_mm=c.path_mm,
                 wall_render_s=res.wall_s[0], wall_sensor_s=res.wall_s[1], wall_control_s=res.wall_s[2],
                 flange2base=res.frame.flange2base, tool2base=c.tool2base, fault=res.fault, health=res.health)


def track(workpiece: Workpiece, rig: Rig, cfg: TrackConfig = TrackConfig(), *,
          sim: SimulationConfig = SimulationConfig(), true_rig: Rig | None = None,
          handeye: tuple[HandEyeResult, np.ndarray] | None = None, seed_px=None,
          listener: TrackListener | None = None) -> TrackRun:
    """Run the closed loop on the workpiece until the torch stops; see the module docstring.

    Parameters
    ----------
    workpiece : Workpiece (base frame)
    rig : Rig (the full camera; the sensor reads ``cfg.roi_rows`` rows of it): what the sensor knows
    cfg : TrackConfig
        The tracking job.
    sim : SimulationConfig
        How the simulated cell renders and where the operator teaches.
    true_rig : Rig or None
        The rig as built, through which the world is rendered (default ``rig``): e.g. the build's true
        geometry while the sensor uses only what was calibrated from images, as on real glass.
    handeye : (HandEyeResult, true cam2flange) or None to run the session first
        (:func:`psvs.robot.handeye_session.calibrate_cell`).
    seed_px : (u, v) or None
        A pixel inside the left view's groove in the first window frame (teaching by showing); None: found
        by :func:`psvs.robot.sensor.auto_seed`.
    listener : TrackListener or None
        Told the start (the calibrated cam2flange and the teach) and every cycle (e.g. to record them). Its
        ``watch``, when it has one (:class:`Watching`), is the rolling self-check (:func:`drift_watch`): it
        reads whole frames through the rig as built, judges them through ``rig`` and, told to, stops the run
        when the calibration has drifted.
    """
    watch = getattr(listener, "watch", None)
    t_enter = time.perf_counter()
    arm = Arm(HOME_Q, sim.limits)
    he, cam_true = handeye if handeye is not None else calibrate_cell(rig, cfg, arm, true_rig=true_rig)
    taught = teach(workpiece, cfg, sim, arm)
    setup, v0 = sensor_setup(rig, cfg, seed_px)
    rows = setup.rig.camera.image_size_px[1]
    roi_true = setup.rig if true_rig is None else roi_rig(true_rig, rows, v0)[0]   # the same rows, as built
    tracker = SeamTracker(cfg, he.cam2flange, taught.taught_mm, taught.travel, window_length_mm(rig, cfg))
    cell = SimulatedCell(arm, workpiece, roi_true, cam_true, cfg.rate_hz, sim, true_rig or rig)
    cycles: list[Cycle] = []
    if listener is not None:
        listener.started(he.cam2flange, taught)

    def record(res: CycleResult) -> None:
        cycles.append(_cycle(res, cell.tcp_mm()))
        if listener is not None:
            listener.cycle(cycles[-1])

    max_cycles = int((workpiece.params["length_mm"] + RUN_IN_OUT_MM) / cfg.speed_mm_s * cfg.rate_hz * 2) + 200
    start_s = time.perf_counter() - t_enter   # set-up (hand-eye calibration included) until the first cycle
    loop = control_loop(cell, tracker, setup, max_cycles, record, watch)
    state = tracker.summary()
    reason = state.stop_reason if tracker.stopped and cell.at_rest() else (state.stop_reason or "cycle limit reached")
    stop = Stop(reason=reason, s_mm=state.s_mm, tcp_mm=cycles[-1].tcp_mm, last_seen_s_mm=state.s_far_mm,
                last_seen_mm=state.last_seen_mm,
                lost_at_s_mm=state.lost_at_s_mm if state.stopping_at_s_mm is not None else None,
                decided_at_s_mm=state.decided_at_s_mm, arc_blocked=state.arc_blocked)
    return TrackRun(config=cfg, simulation=sim, cycles=cycles, stop=stop, handeye=he, cam2flange_true=cam_true,
                    teach=taught, seed_px=loop.seed_px, path_knots=state.path_knots,
                    gaps_bridged=state.gaps_bridged, start_s=start_s,
                    health=None if watch is None else watch.summary())


def replay(run: TrackRun, rig: Rig) -> ReplayCell:
    """Run a fresh controller and sensor on a recorded run's frames and flange poses (what a recording
    holds: no simulation), with the run's configuration, hand-eye transform, teach and seed, and ``rig`` as
    the sensor's rig; returns the replay cell, whose ``mismatches`` lists the cycles where the command
    differs from the recorded one (none: the controller is deterministic)."""
    frames = [Frame(c.t_s, c.flange2base, c.image) for c in run.cycles]
    cell = ReplayCell(frames, [c.tool2base for c in run.cycles], [c.fault for c in run.cycles])
    halts = [c.health.halt if c.health is not None else "" for c in run.cycles]
    holds = [bool(c.health is not None and c.health.arc_held) for c in run.cycles]
    return replay_cell(run.config, run.handeye.cam2flange, run.teach, run.seed_px, cell, rig, halts, holds)


def replay_cell(cfg: TrackConfig, cam2flange: np.ndarray, taught: Teach, seed_px, cell: ReplayCell,  # noqa: PLR0913
                rig: Rig, halts: list[str] | None = None, holds: list[bool] | None = None) -> ReplayCell:
    """:func:`replay` from its parts (e.g. read from a recording, :mod:`psvs.robot.recording`): seed_px None
    finds the seed on the first frame as the live run did; ``halts`` the stop reasons the run's self-check gave
    its controller, per cycle ('' none), and ``holds`` whether it held the torch short of the arc's start (None:
    never). Returns ``cell`` once played."""
    setup, _ = sensor_setup(rig, cfg, seed_px)
    tracker = SeamTracker(cfg, cam2flange, np.asarray(taught.taught_mm, float), np.asarray(taught.travel, float),
                          window_length_mm(rig, cfg))
    recorded = (halts and any(halts)) or (holds and any(holds))
    control_loop(cell, tracker, setup, len(cell.frames), watch=RecordedHalts(halts or [], holds) if recorded else None)
    return cell
