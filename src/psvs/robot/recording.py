"""A seam-tracking run on Foxglove's channels (:mod:`psvs.io.telemetry`): what ``psvs track --foxglove``
shows live and ``--mcap`` records, and what :func:`read_recording` / :func:`replay_recording` read back.

Besides Foxglove's channels (the sensor window on /psvs/image, the seam points on /psvs/points in the base
frame, base_link -> flange -> psvs_optical_frame and flange -> torch on /tf, the path model and the torch
path on /psvs/seam, status on /psvs/log), a recording holds what the controller needs to run again,
exactly:

- ``/psvs/setup`` (once, at t = 0): the TrackConfig, the hand-eye transform cam2flange, the teach point,
  the taught direction of travel, the seed pixel (null: found on the first frame) and the rig the sensor
  measured through (``rig``: a rig file's values; recordings before it have none), which a replay compares
  with the rig it is given;
- ``/psvs/cycle`` (every frame): t_s, the flange pose flange2base at the exposure (the controller's
  input), the torch pose tool2base commanded (its output), the arm's fault, and the controller's state
  (s_mm, valid, reason) for reading, and the stop the self-check gave the controller on it (``halt``, '' none:
  a replay halts there too). Matrices as 16 row-major floats in mm, written exactly (JSON repr);
- ``/psvs/stop`` (once, at the last cycle): why the run ended. A recording without it was cut short
  (e.g. Ctrl-C): it still replays, and the replay says so;
- ``/psvs/health`` (with the rolling self-check, psvs.robot.drift: each cycle it judged): the frame, the
  verdict, the twins' field RMS and uncertainty (px), the tiles and the check's share of the sensor's time,
  as ``psvs live`` records it; what it says on /psvs/log.

The frames are /psvs/image's mono8 bytes, losslessly. Everything shares one log time per cycle.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from psvs.health.rolling import health_record
from psvs.io.params import rig_from_dict, rig_to_dict
from psvs.io.telemetry import BASE_FRAME, CAMERA_FRAME, FLANGE_FRAME, TORCH_FRAME
from psvs.optics.rig import Rig
from psvs.robot.cells import Frame, ReplayCell
from psvs.robot.controller import TrackConfig
from psvs.robot.loop import Teach, replay_cell
from psvs.robot.mounting import tool2flange

#: Every topic of a ``psvs track`` recording.
TOPICS = ("/psvs/setup", "/psvs/cycle", "/psvs/image", "/psvs/points", "/tf", "/psvs/seam", "/psvs/log",
          "/psvs/stop")
#: Simulation settings that recordings written before they had their own record (SimulationConfig) kept in
#: their configuration: they do not change what the controller does, and are left out when read.
SIMULATION_KEYS = ("start_offset_mm", "supersample", "noise_seed")
#: The torch path shown on /psvs/seam: a point every TORCH_STEP_MM, the last TORCH_POINTS of them.
TORCH_STEP_MM, TORCH_POINTS = 1.0, 500


def _mat(a) -> list[float]:
    return [float(x) for x in np.asarray(a, float).ravel()]


def publish_setup(tel, cfg: TrackConfig, cam2flange: np.ndarray, teach: Teach, seed_px, rig: Rig | None = None) -> None:
    """The run's /psvs/setup record and a status line; with ``rig``, the rig the sensor measured through (as a
    rig file's values: :func:`psvs.io.params.rig_to_dict`), so that a replay can say it was given another."""
    setup = {"config": {k: getattr(cfg, k) for k in cfg.__dataclass_fields__}, "cam2flange": _mat(cam2flange),
             "taught_mm": _mat(teach.taught_mm), "travel": _mat(teach.travel),
             "seed_px": None if seed_px is None else _mat(seed_px)}
    if rig is not None:
        setup["rig"] = rig_to_dict(rig)
    tel.record("setup", 0.0, setup)
    tel.log(0.0, f"tracking at {cfg.speed_mm_s:g} mm/s, {cfg.rate_hz:g} Hz")


def publish_stop(tel, t_s: float, reason: str) -> None:
    """The run's /psvs/stop record and a status line, at the last cycle's time."""
    tel.record("stop", t_s, {"reason": reason})
    tel.log(t_s, f"stop: {reason}")


class CyclePublisher:
    """Publishes every control cycle (psvs.robot.loop.Cycle) of a run: call it with each cycle."""

    def __init__(self, tel, cam2flange: np.ndarray, tool2flange: np.ndarray):
        self.tel, self.cam, self.tool = tel, cam2flange, tool2flange
        self.torch: list[np.ndarray] = []
        self._last_reason, self.cycles = None, 0

    def __call__(self, c) -> None:
        tel, t = self.tel, c.t_s
        tel.record("cycle", t, {"t_s": t, "flange2base": _mat(c.flange2base), "tool2base": _mat(c.tool2base),
                                "fault": c.fault, "s_mm": c.s_mm, "valid": bool(c.valid), "reason": c.reason,
                                "halt": c.health.halt if c.health is not None else "",
                                "arc_held": bool(c.health is not None and c.health.arc_held)})
        tel.image(t, c.image)
        tel.points(t, c.points_mm, frame_id=BASE_FRAME)
        tel.transforms(t, [(BASE_FRAME, FLANGE_FRAME, c.flange2base), (FLANGE_FRAME, CAMERA_FRAME, self.cam),
                           (FLANGE_FRAME, TORCH_FRAME, self.tool)])
        if not self.torch or np.linalg.norm(c.tcp_mm - self.torch[-1]) >= TORCH_STEP_MM:
            self.torch = self.torch[-(TORCH_POINTS - 1):] + [np.asarray(c.tcp_mm, float)]
        tel.lines(t, {"taught_seam": c.path_mm, "torch_path": np.array(self.torch + [c.tcp_mm])})
        h = c.health
        if h is not None and h.judged:
            tel.record("health", t, health_record(h.check, self.cycles, h.cost_share))
        if h is not None and h.line:
            tel.log(t, h.line, "info" if h.check.verdict == "healthy" else "warning")
        self.cycles += 1
        if c.fault:
            tel.log(t, f"arm fault: {c.fault}", "error")
        elif c.reason != self._last_reason and c.reason:
            tel.log(t, c.reason, "info" if c.valid else "warning")
        self._last_reason = c.reason


class RunRecorder:
    """Records a run as it happens (a :class:`psvs.robot.loop.TrackListener`): /psvs/setup when it starts,
    then every cycle (:class:`CyclePublisher`)."""

    def __init__(self, tel, cfg: TrackConfig, seed_px, rig: Rig | None = None):
        self.tel, self.cfg, self.seed_px, self.rig = tel, cfg, seed_px, rig
        self._publish: CyclePublisher | None = None

    def started(self, cam2flange: np.ndarray, teach: Teach) -> None:
        """Publish the run's set-up (the mount, the taught start, the seed, the rig) before the first cycle."""
        publish_setup(self.tel, self.cfg, cam2flange, teach, self.seed_px, self.rig)
        self._publish = CyclePublisher(self.tel, cam2flange, tool2flange())

    def cycle(self, cycle) -> None:
        """Publish one control cycle's record on the run's channels."""
        self._publish(cycle)


@dataclass(frozen=True, eq=False)
class Recording:
    """A recorded run: its configuration, hand-eye transform (4, 4), the teach, seed (u, v) or None, and
    per cycle the frame, the command tool2base (4, 4) and the fault."""

    config: TrackConfig
    cam2flange: np.ndarray
    teach: Teach
    seed_px: tuple[float, float] | None
    frames: list[Frame]
    commands: list[np.ndarray]
    faults: list[str]
    stop_reason: str | None        # None: the recording was cut short
    halts: list[str] | None = None  # the stop reason the self-check gave on each cycle ('' none)
    holds: list[bool] | None = None  # whether the self-check held the torch short of the arc's start on each
    rig: Rig | None = None          # the rig the sensor measured through (recordings before it: None)


def read_recording(path) -> Recording:
    """Read a ``psvs track --mcap`` file with the ``mcap`` reader (images decoded with protobuf from the
    schema the file carries). ValueError names what is missing or unreadable."""
    try:
        rec = _read(path)
    except FileNotFoundError:
        raise
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    except Exception as exc:       # the mcap reader's, zstd's and protobuf's errors: a damaged file
        raise ValueError(f"cannot read the recording {path}: the file is damaged or cut short (the MCAP reader "
                         f"said: {str(exc) or type(exc).__name__})") from None
    return rec


def _read(path) -> Recording:
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
    from mcap.reader import make_reader
    setup, stop, cycles, images = None, None, {}, {}
    image_cls = None
    with open(path, "rb") as f:
        for schema, channel, msg in make_reader(f).iter_messages(
                topics=["/psvs/setup", "/psvs/cycle", "/psvs/image", "/psvs/stop"]):
            if channel.topic == "/psvs/setup":
                setup = json.loads(msg.data)
            elif channel.topic == "/psvs/stop":
                stop = json.loads(msg.data)["reason"]
            elif channel.topic == "/psvs/cycle":
                cycles[msg.log_time] = json.loads(msg.data)
            else:
                if image_cls is None:
                    if schema is None or schema.encoding != "protobuf":
                        raise ValueError("/psvs/image has no protobuf schema")
                    pool = descriptor_pool.DescriptorPool()
                    for fd in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file:
                        pool.Add(fd)
                    image_cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
                images[msg.log_time] = image_cls.FromString(msg.data)
    if setup is None or not cycles:
        raise ValueError("not a psvs track recording: no /psvs/setup or /psvs/cycle messages")
    missing = sorted(set(cycles) - set(images))
    if missing:
        raise ValueError(f"{len(missing)} cycles have no /psvs/image frame")
    frames, commands, faults, halts, holds = [], [], [], [], []
    try:
        for ns in sorted(cycles):
            c, img = cycles[ns], images[ns]
            if img.encoding != "mono8" or len(img.data) != img.width * img.height:
                raise ValueError(f"a /psvs/image frame is not {img.width}x{img.height} mono8")
            image = np.frombuffer(img.data, np.uint8).reshape(img.height, img.width)
            frames.append(Frame(_number(c["t_s"], "t_s"), _pose(c["flange2base"], "flange2base"), image))
            commands.append(_pose(c["tool2base"], "tool2base"))
            faults.append(str(c["fault"]))
            halts.append(str(c.get("halt", "")))          # recordings before the self-check have none
            holds.append(_flag(c.get("arc_held", False)))   # nor before the arc's hold
        seed = setup["seed_px"]
        config = {k: v for k, v in setup["config"].items() if k not in SIMULATION_KEYS}
        return Recording(TrackConfig(**config), _pose(setup["cam2flange"], "cam2flange"),
                         Teach(_vector(setup["taught_mm"], "taught_mm"), _direction(setup["travel"])),
                         None if seed is None else tuple(_vector(seed, "seed_px", 2)), frames, commands, faults,
                         stop, halts, holds, _recorded_rig(setup.get("rig")))
    except (KeyError, TypeError) as exc:
        raise ValueError(f"a /psvs/setup or /psvs/cycle record lacks or mistypes {exc}") from None


def _number(v, what: str) -> float:
    """A recorded finite number (ValueError naming ``what`` otherwise)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise ValueError(f"a recorded {what} is not a finite number: {v!r}")
    return float(v)


def _vector(v, what: str, n: int = 3) -> np.ndarray:
    """A recorded list of ``n`` finite numbers as float64 (n,) (ValueError naming ``what`` otherwise)."""
    if not isinstance(v, list) or len(v) != n:
        raise ValueError(f"a recorded {what} is not a list of {n} numbers")
    return np.array([_number(x, what) for x in v])


def _pose(v, what: str) -> np.ndarray:
    """A recorded pose: 16 finite numbers, row-major, a rigid transform (ValueError naming ``what``)."""
    from psvs.transforms import check_transform
    return check_transform(_vector(v, what, 16).reshape(4, 4), f"the recorded {what}")


def _direction(v) -> np.ndarray:
    """The recorded direction of travel: 3 finite numbers of unit length (as the teach writes it)."""
    d = _vector(v, "travel")
    if abs(np.linalg.norm(d) - 1.0) > 1e-6:
        raise ValueError(f"the recorded direction of travel is not a unit vector (length {np.linalg.norm(d):.6g})")
    return d


def replay_recording(path, rig):
    """Run a fresh controller and seam sensor (over ``rig``) on a recording's frames and flange poses:
    :func:`psvs.robot.loop.replay_cell`; returns (the :class:`Recording`, the replay cell: ``mismatches``
    empty when every command was reproduced)."""
    rec = read_recording(path)
    w, h = rig.camera.image_size_px
    widths = {f.image.shape[1] for f in rec.frames}
    if widths - {w}:                    # (was the window's "camera is 1440x34 px", a trial found)
        raise ValueError(f"{path}: its frames are {min(widths - {w})} px wide but the rig's camera is {w}x{h} px: "
                         "replay it with the rig the run was recorded with")
    if rec.rig is not None and rec.rig != rig:
        differ = _differences(rig_to_dict(rec.rig), rig_to_dict(rig))
        raise ValueError(f"{path} was recorded through another rig than the one given (they differ in "
                         f"{', '.join(differ[:4])}{' ...' if len(differ) > 4 else ''}): replay it with the rig the "
                         "run was recorded with")
    cell = ReplayCell(rec.frames, rec.commands, rec.faults)
    return rec, replay_cell(rec.config, rec.cam2flange, rec.teach, rec.seed_px, cell, rig, rec.halts, rec.holds)


def _recorded_rig(values) -> Rig | None:
    """The recorded rig (None when the recording has none), ValueError when it is no rig."""
    if values is None:
        return None
    try:
        return rig_from_dict(values)
    except (ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"the recorded rig is not a rig: {exc}") from None


def _differences(a: dict, b: dict, prefix: str = "") -> list[str]:
    """The keys (dotted, e.g. camera.focal_length_mm) whose values differ between two rig files' tables."""
    out = []
    for key in sorted(set(a) | set(b)):
        va, vb = a.get(key), b.get(key)
        if isinstance(va, dict) and isinstance(vb, dict):
            out += _differences(va, vb, f"{prefix}{key}.")
        elif va != vb:
            out.append(f"{prefix}{key}")
    return out


def _flag(v) -> bool:
    """A recorded flag: a JSON boolean (TypeError otherwise, which the reader names)."""
    if not isinstance(v, bool):
        raise TypeError("arc_held")
    return v
