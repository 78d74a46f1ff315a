"""The web page's calibration job: ``psvs calibrate`` on a folder of card views in a background thread, one at
a time (psvs.web.api_calibrate)."""
from __future__ import annotations

from pathlib import Path

from psvs.web.job import OneJob

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


class CalibrationJob(OneJob):
    """One calibration at a time in a background thread; :meth:`state` for the page."""

    def __init__(self):
        super().__init__("a calibration is running: wait for it", folder=None, result=None)

    def start(self, folder: Path, start_rig, on_done) -> None:
        """Calibrate ``folder`` from ``start_rig``; ``on_done(rig, path)`` with the calibrated rig once its
        file is written."""
        self._start("psvs-calibrate", lambda: self._run(folder, start_rig, on_done), folder=str(folder))

    def _run(self, folder: Path, start_rig, on_done) -> None:
        from psvs.calibrate.folder import calibrate_folder
        from psvs.io.params import save_rig
        res = calibrate_folder(folder, start_rig)
        b = res.bundle
        if not b.success:
            raise ValueError(f"the bundle adjustment did not converge: {b.message}")
        rig, path = res.recorded_rig(), free_rig_name(folder / RIG_FILE)
        save_rig(rig, path)
        on_done(rig, path)
        self._update(result={"rms_px": b.rms_px, "rms_left_px": b.rms_by_view["left"],
                             "rms_right_px": b.rms_by_view["right"], "used": len(res.used), "kinds": res.kinds,
                             "skipped": dict(sorted(res.skipped.items())), "baseline_mm": res.baseline_mm,
                             "baseline_sigma_mm": res.baseline_sigma_mm, "held_by_prior": list(b.held_by_prior),
                             "file": str(path)})

    def state(self) -> dict:
        """{running, folder, error ('' none), result (None until one succeeded)}, for the page to poll."""
        return super().state()
