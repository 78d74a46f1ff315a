"""The web page's seam-tracking run: ``psvs track`` on a simulated cell in a background thread, one at a time
(psvs.web.api_robot): the closed loop with its rolling self-check, its report and log written into a scratch
folder and kept as text, as the page would read a run ``psvs track -o RUN`` wrote."""
from __future__ import annotations

import tempfile
from pathlib import Path

from psvs.web.job import OneJob


class TrackJob(OneJob):
    """One run at a time; :meth:`state` for the page to poll."""

    def __init__(self):
        super().__init__("a tracking run is under way: wait for it", cycles=0, expected=0, files=None, rig=None)

    def start(self, rig, cfg, workpiece, expected: int) -> None:
        """Track ``workpiece`` (psvs.robot.workpiece) with ``rig`` and ``cfg`` (psvs.robot.controller.TrackConfig),
        ``expected`` control cycles; ValueError while one runs."""
        self._start("psvs-track", lambda: self._run(rig, cfg, workpiece), expected=int(expected), rig=rig)

    def started(self, cam2flange, teach) -> None:
        """The loop's listener: the run started (after its hand-eye session)."""

    def cycle(self, c) -> None:
        """The loop's listener: one control cycle done."""
        with self._lock:
            self._state["cycles"] += 1

    def _run(self, rig, cfg, workpiece) -> None:
        from psvs.robot.loop import Watching, drift_watch, track
        from psvs.robot.report import write_report
        result = track(workpiece, rig, cfg, listener=Watching(drift_watch(rig, cfg), self))
        with tempfile.TemporaryDirectory(prefix="psvs-track-") as tmp:
            write_report(result, workpiece, tmp)
            files = {name: (Path(tmp) / name).read_text() for name in ("log.csv", "report.json")}
        self._update(files=files)

    def state(self) -> dict:
        """{running, cycles (done), expected, error ('' none), files ({log.csv, report.json} texts once done, else
        None), rig (the rig it tracked with)}."""
        return super().state()
