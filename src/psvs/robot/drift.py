"""The rolling self-check riding a seam-tracking run (docs/health.md): is the calibration the sensor tracks
with still the glass it looks through?

The seam sensor reads a window of a few dozen rows; the check needs tiles over the whole field. The camera
grabs whole frames (the window is cut from them, as the paper's frame grabber did), so when the check's
credit (:class:`psvs.health.rolling.RollingCheck`: a share of the sensor's own time) covers a step, the cell
hands it the whole frame of that cycle (:meth:`psvs.robot.cells.SimulatedCell.full_frame`; in simulation it
is rendered then, which is the simulation's cost, not the sensor's). The step reads the frame's next tiles
of the workpiece's texture and judges the last sweep as ``psvs check`` judges a frame. When the verdict
crosses the tolerance the run says one line, and, told to, stops safely: the torch brakes at the
controller's deceleration (:meth:`psvs.robot.controller.SeamTracker.halt`) and the arc goes off there.
"""
from __future__ import annotations

from dataclasses import dataclass

from psvs.health.check import HealthCheck
from psvs.health.rolling import RollingCheck

#: How the stop reason of a run its self-check stopped begins.
DRIFT_STOP = "calibration drifted"


@dataclass(frozen=True, eq=False)
class HealthNote:
    """The check as of one control cycle: ``check`` its latest judgement (None before its first), ``judged``
    whether it took a step on this cycle, ``line`` what it said on this cycle ('' nothing), ``cost_share``
    its time over the sensor's so far, ``halt`` the stop reason it gave the controller on this cycle ('' none:
    a recording keeps it, so that a replay halts there too)."""

    check: HealthCheck | None
    judged: bool
    line: str
    cost_share: float
    halt: str = ""


class DriftWatch:
    """The rolling check of a track run (module docstring): ``check`` a RollingCheck over the sensor's rig
    (what it was calibrated to) and depth range; ``stop_on_drift`` halts the run when it turns drifted."""

    def __init__(self, check: RollingCheck, stop_on_drift: bool = False):
        self.check, self.stop_on_drift = check, bool(stop_on_drift)
        self.lines: list[str] = []

    def look(self, cell, cycle: int, sensor_s: float, tracker) -> HealthNote:
        """After cycle ``cycle``'s sensing (``sensor_s`` s of the sensor's time): a step on the cell's whole
        frame when one is due; a drifted verdict halts ``tracker`` when told to."""
        judged = self.check.due(sensor_s)
        event = self.check.take(cell.full_frame(), cycle) if judged else None
        line = halt = ""
        if event is not None:
            line = event.line
            self.lines.append(line)
            if self.stop_on_drift and event.check.verdict == "drifted":
                halt = f"{DRIFT_STOP} at frame {cycle}: {event.check.reason}"
                tracker.halt(halt)
        return HealthNote(self.check.latest, judged, line, self.check.cost_share, halt)

    def summary(self) -> dict:
        """The run's check for its report (JSON-ready): :meth:`RollingCheck.summary` and every ``lines`` said."""
        return {**self.check.summary(), "lines": list(self.lines), "stop_on_drift": self.stop_on_drift}


class RecordedHalts:
    """A recorded run's halts played back (a replay: no frames to check): ``halts`` the stop reason given on
    each cycle ('' none), given to the controller on the same cycles."""

    def __init__(self, halts: list[str]):
        self.halts = list(halts)

    def look(self, cell, cycle: int, sensor_s: float, tracker) -> None:
        """Halt ``tracker`` on the cycles the recorded run halted."""
        if cycle < len(self.halts) and self.halts[cycle]:
            tracker.halt(self.halts[cycle])
