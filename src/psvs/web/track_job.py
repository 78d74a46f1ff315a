"""The web page's seam-tracking run: ``psvs track`` on a simulated cell in a background thread, one at a time
(psvs.web.api_robot): the closed loop with its rolling self-check, its report and log written into a scratch
folder and kept as text, as the page would read a run ``psvs track -o RUN`` wrote."""
from __future__ import annotations

import tempfile
import threading
from pathlib import Path


class TrackJob:
    """One run at a time; :meth:`state` for the page to poll."""

    def __init__(self):
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._state = {"running": False, "cycles": 0, "expected": 0, "error": "", "files": None, "rig": None}

    @property
    def running(self) -> bool:
        """Whether a run is under way."""
        return self._thread is not None and self._thread.is_alive()

    def start(self, rig, cfg, workpiece, expected: int) -> None:
        """Track ``workpiece`` (psvs.robot.workpiece) with ``rig`` and ``cfg`` (psvs.robot.controller.TrackConfig),
        ``expected`` control cycles; ValueError while one runs."""
        with self._lock:
            if self.running:
                raise ValueError("a tracking run is under way: wait for it")
            self._state = {"running": True, "cycles": 0, "expected": int(expected), "error": "", "files": None,
                           "rig": rig}
            self._thread = threading.Thread(target=self._run, args=(rig, cfg, workpiece), daemon=True,
                                            name="psvs-track")
            self._thread.start()

    def started(self, cam2flange, teach) -> None:
        """The loop's listener: the run started (after its hand-eye session)."""

    def cycle(self, c) -> None:
        """The loop's listener: one control cycle done."""
        with self._lock:
            self._state["cycles"] += 1

    def _run(self, rig, cfg, workpiece) -> None:
        from psvs.robot.loop import Watching, drift_watch, track
        from psvs.robot.report import write_report
        try:
            result = track(workpiece, rig, cfg, listener=Watching(drift_watch(rig, cfg), self))
            with tempfile.TemporaryDirectory(prefix="psvs-track-") as tmp:
                write_report(result, workpiece, tmp)
                files = {name: (Path(tmp) / name).read_text() for name in ("log.csv", "report.json")}
            with self._lock:
                self._state.update(files=files)
        except Exception as exc:              # noqa: BLE001  - said on the page, in one line
            text = str(exc).strip()
            with self._lock:
                self._state.update(error=(text.splitlines()[-1] if text else type(exc).__name__)[:300])
        finally:
            with self._lock:
                self._state.update(running=False)

    def state(self) -> dict:
        """{running, cycles (done), expected, error ('' none), files ({log.csv, report.json} texts once done, else
        None), rig (the rig it tracked with)}."""
        with self._lock:
            return dict(self._state)
