"""The web page's calibration job: ``psvs calibrate`` on a folder of card views in a background thread, one at
a time (psvs.web.api_calibrate)."""
from __future__ import annotations

import threading
from pathlib import Path

#: The rig file a calibration writes into its folder.
RIG_FILE = "build.toml"


def free_rig_name(path: Path) -> Path:
    """``path``, or build-2.toml, build-3.toml ... beside it when it exists: a calibration never replaces a
    rig file already in the folder (an earlier calibration's, or the user's)."""
    k = 1
    while path.exists():
        k += 1
        path = path.with_name(f"{Path(RIG_FILE).stem}-{k}{Path(RIG_FILE).suffix}")
    return path


class CalibrationJob:
    """One calibration at a time in a background thread; :meth:`state` for the page."""

    def __init__(self):
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._state = {"running": False, "folder": None, "error": "", "result": None}

    @property
    def running(self) -> bool:
        """Whether a calibration is under way."""
        return self._thread is not None and self._thread.is_alive()

    def start(self, folder: Path, start_rig, on_done) -> None:
        """Calibrate ``folder`` from ``start_rig``; ``on_done(rig, path)`` with the calibrated rig once its
        file is written."""
        with self._lock:
            if self.running:
                raise ValueError("a calibration is running: wait for it")
            self._state = {"running": True, "folder": str(folder), "error": "", "result": None}
            self._thread = threading.Thread(target=self._run, args=(folder, start_rig, on_done), daemon=True,
                                            name="psvs-calibrate")
            self._thread.start()

    def _run(self, folder: Path, start_rig, on_done) -> None:
        from psvs.calibrate.folder import calibrate_folder
        from psvs.io.params import save_rig
        try:
            res = calibrate_folder(folder, start_rig)
            b = res.bundle
            if not b.success:
                raise ValueError(f"the bundle adjustment did not converge: {b.message}")
            rig, path = res.recorded_rig(), free_rig_name(folder / RIG_FILE)
            save_rig(rig, path)
            on_done(rig, path)
            result = {"rms_px": b.rms_px, "rms_left_px": b.rms_by_view["left"], "rms_right_px": b.rms_by_view["right"],
                      "used": len(res.used), "kinds": res.kinds, "skipped": dict(sorted(res.skipped.items())),
                      "baseline_mm": res.baseline_mm, "baseline_sigma_mm": res.baseline_sigma_mm,
                      "held_by_prior": list(b.held_by_prior), "file": str(path)}
            with self._lock:
                self._state.update(result=result)
        except Exception as exc:              # noqa: BLE001  - said on the page, in one line
            text = str(exc).strip()
            with self._lock:
                self._state.update(error=(text.splitlines()[-1] if text else type(exc).__name__)[:300])
        finally:
            with self._lock:
                self._state.update(running=False)

    def state(self) -> dict:
        """{running, folder, error ('' none), result (None until one succeeded)}, for the page to poll."""
        with self._lock:
            return dict(self._state)
