"""Cells: what runs the seam-tracking controller (psvs.robot.controller) on an arm and a camera.

A cell (:class:`Cell`) has four operations, all in the robot's base frame, millimetres and seconds:

- ``read() -> Frame``: the next camera frame (the sensor window of the complex image, (H, W) uint8), its
  time, and the flange pose flange2base (4, 4) *at the frame's exposure* (a real driver interpolates the
  arm's joint readings to the camera's time stamp);
- ``send(tool2base) -> ServoStep | None``: carry out one command, the torch pose to reach by the next frame
  (the cell's inverse kinematics and joint servo); ValueError when the arm cannot (unreachable, a joint
  limit, a configuration switch): the controller then stops;
- ``stop() -> ServoStep | None``: brake for one period;
- ``at_rest() -> bool``: the arm no longer moves.

``send`` and ``stop`` return the arm's joint state after the period, or None from a cell that has no arm to
read (a replay). :func:`control_loop` runs a controller on any cell: read, sensor, controller, send, once
per frame, until the controller has stopped and the arm is at rest. :class:`SimulatedCell` is the PUMA 560
of psvs.robot.arm with the world rendered from the pose the joints really give; :class:`ReplayCell` plays
a recorded run's frames and poses back and checks that the controller sends the recorded commands.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from psvs.live.camera import Acquisition
from psvs.live.camera import Frame as CameraFrame
from psvs.optics.rig import Rig
from psvs.robot.arm import Arm, ArmLimits, ServoStep
from psvs.robot.controller import Command, Observation, SeamTracker
from psvs.robot.drift import DriftWatch, HealthNote, RecordedHalts
from psvs.robot.mounting import tool2flange
from psvs.robot.seam import SeamObservation
from psvs.robot.sensor import SeamSensor, SensorSetup
from psvs.robot.workpiece import Workpiece
from psvs.simulate.geometry import SceneGeometry
from psvs.simulate.sensor import Sensor
from psvs.simulate.sequence import render_from
from psvs.transforms import concat, invert_transform

#: The arm is at rest when every joint turns slower than this (rad/s): the torch then moves < 0.3 mm/s.
REST_SPEED_RAD_S = 1e-4
#: The largest joint change one control cycle may ask for (a path step of < 1 mm moves no joint by
#: more than ~0.01 rad here): more means the solver switched arm configuration.
MAX_IK_STEP_RAD = 0.1
#: The whole frames' noise seeds start here (the sensor windows' at the noise seed): other draws.
FULL_FRAME_SEED = 1_000_003


@dataclass(frozen=True, eq=False)
class Frame:
    """One camera frame: time (s), flange2base (4, 4) mm at its exposure, the image (H, W) uint8."""

    t_s: float
    flange2base: np.ndarray
    image: np.ndarray


class Cell(Protocol):
    """The interface :func:`control_loop` runs a controller on (see the module docstring)."""

    def read(self) -> Frame:
        """The frame of this control cycle."""

    def send(self, tool2base: np.ndarray) -> ServoStep | None:
        """Command the tool pose ``tool2base`` (4, 4) mm for the next cycle."""

    def stop(self) -> ServoStep | None:
        """Bring the arm to rest (no new target)."""

    def at_rest(self) -> bool:
        """Whether the arm has stopped moving."""


@dataclass(frozen=True)
class SimulationConfig:
    """How the simulated cell renders its frames and where the operator teaches the start.

    start_offset_mm : the taught start, this far along the seam from the workpiece's end.
    supersample : render anti-aliasing (samples per pixel side).  noise_seed : sensor noise seed.
    limits : the simulated arm's joint limits and servo rate.
    """

    start_offset_mm: float = 50.0
    supersample: int = 2
    noise_seed: int = 0
    limits: ArmLimits = ArmLimits()

    def __post_init__(self):
        if not isinstance(self.supersample, int) or self.supersample < 1:
            raise ValueError(f"supersample must be an integer >= 1, got {self.supersample!r}")
        if not isinstance(self.noise_seed, int) or self.noise_seed < 0:
            raise ValueError(f"noise_seed must be an integer >= 0, got {self.noise_seed!r}")


class SimulatedCell:
    """The simulated PUMA 560 cell: frames rendered through ``true_roi_rig`` (the sensor window of the rig
    as built) from the camera pose the joints really give (the true mounting ``cam2flange_true``), one per
    control period; commands through the arm's IK and its 500 Hz joint servo."""

    def __init__(self, arm: Arm, workpiece: Workpiece, true_roi_rig: Rig, cam2flange_true: np.ndarray,
                 rate_hz: float, sim: SimulationConfig = SimulationConfig(), true_rig: Rig | None = None):
        self.arm, self.workpiece, self.rig, self.cam2flange = arm, workpiece, true_roi_rig, cam2flange_true
        self.full_rig = true_rig
        self.dt, self.sim = 1.0 / rate_hz, sim
        self._tool = tool2flange()
        self._flange2base = None
        self._scene_geometry: SceneGeometry | None = None
        self.camera = RenderedCamera(self, "simulated sensor window")

    @property
    def k(self) -> int:
        """Frames read so far."""
        return self.camera.index

    def read(self) -> Frame:
        """A frame from the cell's camera (a :class:`psvs.live.camera.FrameSource`, as a real cell's would be,
        e.g. a Basler camera on a hardware trigger), with the flange pose at its exposure."""
        self._flange2base = self.arm.fkine()
        shot = self.camera.grab()
        return Frame(shot.timestamp_s, self._flange2base, shot.image)

    def render_now(self, k: int) -> np.ndarray:
        """Frame ``k`` rendered from the camera pose the joints gave at :meth:`read` (H, W) uint8."""
        world2cam = invert_transform(concat(self.cam2flange, self._flange2base))
        return render_from(self.workpiece.scene, world2cam, self.rig, self._geometry(),
                           supersample=self.sim.supersample, sensor=Sensor(), seed=self.sim.noise_seed + k).image

    def _geometry(self) -> SceneGeometry:
        """The workpiece's ray-tracing geometry, built at the first frame (each frame moves it to the camera)."""
        if self._scene_geometry is None:
            self._scene_geometry = SceneGeometry(self.workpiece.scene)
        return self._scene_geometry

    def full_frame(self) -> np.ndarray:
        """The camera's whole frame (H, W) uint8 at the pose of the last :meth:`read` (the sensor window is
        cut from it), through the whole rig as built (``true_rig``): what the rolling self-check reads."""
        if self.full_rig is None:
            raise ValueError("this cell renders only the sensor window: give it the whole rig as built")
        world2cam = invert_transform(concat(self.cam2flange, self._flange2base))
        return render_from(self.workpiece.scene, world2cam, self.full_rig, self._geometry(),
                           supersample=self.sim.supersample, sensor=Sensor(),
                           seed=FULL_FRAME_SEED + self.sim.noise_seed + self.k).image

    def send(self, tool2base: np.ndarray) -> ServoStep:
        """Command the tool pose ``tool2base`` (4, 4) mm for the next cycle."""
        q_t = self.arm.ikine(concat(invert_transform(self._tool), tool2base), max_step_rad=MAX_IK_STEP_RAD)
        return self.arm.servo(q_t, self.dt)

    def stop(self) -> ServoStep:
        """Bring the arm to rest (no new target)."""
        return self.arm.stop(self.dt)

    def at_rest(self) -> bool:
        """Whether the arm has stopped moving."""
        return bool(np.max(np.abs(self.arm.qd)) < REST_SPEED_RAD_S)

    def tcp_mm(self) -> np.ndarray:
        """(3,) the torch tip where the arm really is."""
        return concat(self._tool, self.arm.fkine())[:3, 3]


@dataclass(frozen=True, eq=False)
class CycleResult:
    """What :func:`control_loop` hands back each cycle: the frame, the sensor's measurement, the command,
    the servo step (None from a cell without an arm to read), the arm's fault ('' none) and the wall
    times (s) of reading, sensing, control."""

    frame: Frame
    seam: SeamObservation
    command: Command
    step: ServoStep | None
    fault: str
    wall_s: tuple[float, float, float]
    health: HealthNote | None = None


@dataclass(frozen=True, eq=False)
class LoopResult:
    """A finished :func:`control_loop`: every cycle, the seam sensor (None if no frame was read) and the
    seed it started from (u, v) px."""

    cycles: list[CycleResult]
    sensor: SeamSensor | None
    seed_px: tuple[float, float] | None


def control_loop(cell: Cell, tracker: SeamTracker, setup: SensorSetup, max_cycles: int,
                 on_cycle: Callable[[CycleResult], None] | None = None,
                 watch: DriftWatch | RecordedHalts | None = None) -> LoopResult:
    """Run ``tracker`` on ``cell`` until it has stopped and the arm is at rest, or ``max_cycles``.

    The seam sensor starts on the first frame (:meth:`SensorSetup.start`) and tracks from every frame the
    controller accepts. ``on_cycle(CycleResult)`` is called after every cycle. ``watch`` (a cell with whole
    frames: :meth:`SimulatedCell.full_frame`) checks the calibration after each cycle's sensing, before the
    controller decides (psvs.robot.drift)."""
    sensor, results, control_s = None, [], 0.0
    for _ in range(max_cycles):
        t0 = time.perf_counter()
        frame = cell.read()
        t1 = time.perf_counter()
        if sensor is None:
            sensor = setup.start(frame.image)
        seam = sensor.measure(frame.image)
        t2 = time.perf_counter()
        note = None if watch is None else watch.look(cell, len(results), t2 - t1, tracker, control_s)
        t2c = time.perf_counter()              # the check's time (and its frame's) is neither sensing nor control
        cmd = tracker.step(Observation(frame.t_s, frame.flange2base, seam))
        if cmd.accepted or (cmd.valid and sensor.half_width_px is None):
            sensor.commit(seam)
        fault = ""
        try:
            step = cell.send(cmd.tool2base)
        except ValueError as exc:
            step, fault = cell.stop(), str(exc)
            tracker.fault(fault)
        t3 = time.perf_counter()
        control_s = t3 - t2c
        res = CycleResult(frame, seam, cmd, step, fault, (t1 - t0, t2 - t1, control_s), note)
        results.append(res)
        if on_cycle is not None:
            on_cycle(res)
        if tracker.stopped and cell.at_rest():
            break
    return LoopResult(results, sensor, None if sensor is None else sensor.seed_px)


class RenderedCamera:
    """The simulated cell's camera as a :class:`psvs.live.camera.FrameSource`: each grab renders the world
    from the pose the arm has at that moment (``cell.render_now``); its clock is the cell's simulated time
    (frame k at k / rate, the "camera" clock); it takes no acquisition settings."""

    frame_count: int = 0

    def __init__(self, cell: SimulatedCell, name: str):
        self.cell, self.name, self.fps, self.index = cell, name, 1.0 / cell.dt, 0

    def open(self) -> None:
        """Nothing to open: the frames are rendered on demand."""
        pass

    def configure(self, acquisition: Acquisition) -> None:
        """The simulated camera takes no acquisition settings (ValueError when any is asked)."""
        if acquisition.asks_anything():
            raise ValueError(f"{self.name} takes no acquisition settings")

    def grab(self) -> CameraFrame:
        """The next frame, rendered where the arm is now."""
        k = self.index
        self.index += 1
        return CameraFrame(self.cell.render_now(k), k, k, k * self.cell.dt, "camera")

    def close(self) -> None:
        """Nothing to close."""
        pass

    def settings(self) -> dict:
        """The source's settings for the run's record: its name and frame rate."""
        return {"source": self.name, "frame_rate_hz": self.fps}

    def feature_file(self) -> str | None:
        """None: a simulated camera has no feature file."""
        return None


class ReplayCell:
    """A recorded run played back: ``frames`` (each :class:`Frame`), the commands the live controller
    sent (tool2base (4, 4) each) and the arm's faults ('' none) per frame. ``send`` records what the
    controller sends now and raises the recorded fault where there was one; the arm is at rest when the
    recording ends. No arm is read: ``send`` and ``stop`` return None. :attr:`mismatches` lists the
    frames whose command differs from the recorded one."""

    def __init__(self, frames: list[Frame], commands: list[np.ndarray], faults: list[str] | None = None):
        if len(frames) != len(commands):
            raise ValueError(f"a recording needs one command per frame: {len(frames)} frames, {len(commands)} commands")
        self.frames, self.recorded = frames, [np.asarray(c, float) for c in commands]
        self.faults = faults or [""] * len(frames)
        self.k, self.sent, self.mismatches = 0, [], []

    def read(self) -> Frame:
        """The next recorded frame (ValueError after the last)."""
        if self.k >= len(self.frames):
            raise ValueError(f"the recording ends after {len(self.frames)} frames")
        self.k += 1
        return self.frames[self.k - 1]

    def send(self, tool2base: np.ndarray) -> None:
        """Take the controller's command ``tool2base`` (4, 4) mm, compare it with the recorded one, and raise the
        fault the run recorded at this cycle, if any."""
        k = self.k - 1
        self.sent.append(np.array(tool2base, float))
        if not np.array_equal(self.sent[-1], self.recorded[k]):
            self.mismatches.append(k)
        if self.faults[k]:
            raise ValueError(self.faults[k])

    def stop(self) -> None:
        """Nothing to stop: a replay moves no arm."""
        return None

    def at_rest(self) -> bool:
        """Whether the recording has been played to its end."""
        return self.k >= len(self.frames)
