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

A run told to stop on drift also sweeps the field before the arc is struck (the run-in,
:attr:`psvs.robot.controller.TrackConfig.arc_on_mm`): until it has read every place of the field once, the
check takes a step on every cycle, on the run-in's idle time (the arc is not struck; the control period less
the sensor's and the controller's time is about 30 of 40 ms, and a step takes 20-70 ms). Which frames it
judges is thus the run-in's first cycles on any machine, not what a loaded machine's clock leaves: a sweep
scheduled by measured idle time once ran on a busy machine only while the torch stood held at the arc's
start, all its steps on one still frame, and judged differently. The steps that overran their cycle's idle
time are counted (``late_steps``: on a real cell, the cycles whose command came late while the torch ran in);
the run-in's steps are not counted in the check's share of the sensor's time. (A simulated cell renders a
whole frame for each step, which is why a run that is not told to stop leaves the sweep out.) Once the check
has halted the run its verdict stands: it takes no more steps while the torch brakes. The arc waits for the
sweep: until it is done the torch is held short of the arc's start
(:meth:`psvs.robot.controller.SeamTracker.hold_arc`; on the shipped builds at 10 mm/s the sweep ends long
before the torch gets there, at 25 mm/s and 5 Hz it may not). A sweep that cannot judge (too little texture
to tell) says so in one line when it releases the arc: the weld goes on unchecked until the check can judge;
one that reads the field beyond the tolerance by more than its uncertainty (:data:`LIKELY_SIGMAS`) halts the
run there instead, no arc struck.
"""
from __future__ import annotations

from dataclasses import dataclass

from psvs.health.check import HealthCheck
from psvs.health.rolling import RollingCheck
from psvs.io.jsonsafe import json_safe

#: How the stop reason of a run its self-check stopped begins.
DRIFT_STOP = "calibration drifted"
#: A run-in's sweep that cannot judge yet reads the field beyond the tolerance by more than this many of its
#: uncertainties (a drift more likely than not: 84 % one-sided) halts the run before the arc. An adversarial
#: trial's M2 leaned 0.05 deg (1.44 px), run in at 60 mm/s and 4 Hz: its sweep read 1.45 +- 0.56 px, `cannot
#: judge`, and the arc was struck; the undrifted build's sweep of the seam plates reads 0.0-0.45 +- 0.5 px.
LIKELY_SIGMAS = 1.0


@dataclass(frozen=True, eq=False)
class HealthNote:
    """The check as of one control cycle: ``check`` its latest judgement (None before its first), ``judged``
    whether it took a step on this cycle, ``line`` what it said on this cycle ('' nothing), ``cost_share``
    its time over the sensor's so far, ``halt`` the stop reason it gave the controller on this cycle ('' none)
    and ``arc_held`` whether it held the torch short of the arc's start (a recording keeps both, so that a replay
    halts and holds there too)."""

    check: HealthCheck | None
    judged: bool
    line: str
    cost_share: float
    halt: str = ""
    arc_held: bool = False


class DriftWatch:
    """The rolling check of a track run (module docstring): ``check`` a RollingCheck over the sensor's rig
    (what it was calibrated to) and depth range; ``stop_on_drift`` halts the run when it turns drifted, and
    sweeps the field on the run-in's cycles, the arc waiting for it."""

    def __init__(self, check: RollingCheck, stop_on_drift: bool = False):
        self.check, self.stop_on_drift = check, bool(stop_on_drift)
        self.lines: list[str] = []
        self.before_arc = None
        self.halted = False
        self.late_steps = 0

    def look(self, cell, cycle: int, sensor_s: float, tracker, control_s: float = 0.0) -> HealthNote:
        """After cycle ``cycle``'s sensing (``sensor_s`` s of the sensor's time; ``control_s`` s the
        controller's, as of the last cycle): a step on the cell's whole frame when one is due, and on every
        cycle of the run-in until the field is swept (module docstring); a drifted verdict halts ``tracker`` when
        told to."""
        if self.halted:
            return HealthNote(self.check.latest, False, "", self.check.cost_share, arc_held=tracker.arc_held)
        run_in = self.stop_on_drift and not tracker.arc_struck and not self.check.swept
        judged = self.check.due(sensor_s) or run_in
        event = self.check.take(cell.full_frame(), cycle, idle=run_in) if judged else None
        if run_in and self.check.last_step_s > 1.0 / tracker.cfg.rate_hz - sensor_s - control_s:
            self.late_steps += 1
        if judged and not tracker.arc_struck:
            self.before_arc = self.check.latest
        line = halt = ""
        if event is not None:
            line = event.line
            if self.stop_on_drift and event.check.verdict == "drifted":
                halt = f"{DRIFT_STOP} at frame {cycle}: {event.check.reason}"
                tracker.halt(halt)
                self.halted = True
        elif run_in and self.check.swept and self.check.latest.verdict == "cannot judge":
            line, halt = self._undecided(cycle, tracker)
        if line:
            self.lines.append(line)
        if self.stop_on_drift:
            tracker.hold_arc(not self.check.swept and not self.halted)
        return HealthNote(self.check.latest, judged, line, self.check.cost_share, halt, tracker.arc_held)

    def _undecided(self, cycle: int, tracker) -> tuple[str, str]:
        """(line, halt) when the run-in's sweep ends and cannot judge: the arc struck unchecked, said; or, when
        its field stands beyond the tolerance by more than :data:`LIKELY_SIGMAS` of its uncertainty (a drift
        more likely than not, which too few tiles or too much scatter keep from being confirmed), the run
        halted before the arc."""
        c = self.check.latest
        rms, unc = c.row_offset_rms_px, c.uncertainty_px
        if not rms - LIKELY_SIGMAS * unc > c.tolerance_px:                    # NaN (no field read): not beyond
            return (f"frame {cycle}: the self-check cannot judge the calibration before the arc: {c.reason}; the "
                    f"arc is struck unchecked (a drift stops the run once it can judge)"), ""
        halt = (f"{DRIFT_STOP} as far as the self-check can tell before the arc, at frame {cycle}: the twins "
                f"{rms:.2f} +- {unc:.2f} px off their rows, beyond the tolerance of {c.tolerance_px:g} px, though "
                f"it cannot judge: {c.reason}")
        tracker.halt(halt)
        self.halted = True
        return (f"frame {cycle}: the calibration has likely drifted: the twins {rms:.2f} +- {unc:.2f} px off their "
                f"rows before the arc (tolerance {c.tolerance_px:g} px), though the self-check cannot judge; the "
                f"arc is not struck"), halt

    def summary(self) -> dict:
        """The run's check for its report (JSON-ready): :meth:`RollingCheck.summary`, every ``lines`` said, and
        ``before_arc``: the verdict, figure and tiles of its last judgement before the arc was struck (None when
        it judged nothing then)."""
        b = self.before_arc
        before = None if b is None else json_safe({"verdict": b.verdict, "row_offset_rms_px": b.row_offset_rms_px,
                                                   "uncertainty_px": b.uncertainty_px, "tiles": b.tiles})
        return {**self.check.summary(), "lines": list(self.lines), "stop_on_drift": self.stop_on_drift,
                "before_arc": before, "late_steps": self.late_steps}


class RecordedHalts:
    """A recorded run's halts and holds played back (a replay: no frames to check): ``halts`` the stop reason
    given on each cycle ('' none), ``holds`` whether the torch was held short of the arc's start on each (None:
    never), given to the controller on the same cycles."""

    def __init__(self, halts: list[str], holds: list[bool] | None = None):
        self.halts, self.holds = list(halts), list(holds or ())

    def look(self, cell, cycle: int, sensor_s: float, tracker, control_s: float = 0.0) -> None:
        """Halt and hold ``tracker`` on the cycles the recorded run did."""
        if cycle < len(self.halts) and self.halts[cycle]:
            tracker.halt(self.halts[cycle])
        tracker.hold_arc(cycle < len(self.holds) and self.holds[cycle])
