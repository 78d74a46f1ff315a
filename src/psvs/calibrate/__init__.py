"""Calibrating a build: bundle adjustment of the exact optics from hand-held card views and/or the paper's
robot sweep, and keeping it in the field.

``folder`` reads a calibration folder (card views, ``sweep.csv``, ``target.toml``) and calls ``bundle``
(the lens, the plate, the mirrors' pose errors and every target pose); ``sweep`` is the robot sweep as
calibration data; ``capture`` is the assistant that says which card views are good and when there are
enough; ``synthetic`` and ``handheld`` simulate card views and a hand-held video; ``report`` writes a
calibration's residuals. ``refit`` re-fits a drifted calibration's mirrors from ordinary frames, ``tare``
its depth on flat surfaces at known distances (``psvs refit``). Targets are found by :mod:`psvs.targets`.
"""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "bundle": ["ASPECT", "ASPECT_SCORE_LIMIT", "BundleResult", "PRIOR_SIGMA", "aspect_score", "bundle_adjust",
                   "covariance"],
        "capture": ["CaptureAssistant", "CaptureFolder", "CaptureParams", "CaptureStep", "check_capture_folder",
                    "check_card_visible", "event_lines"],
        "folder": ["calibrate_folder", "grid_view"],
        "handheld": ["HandParams", "hand_path", "render_hand_video"],
        "misfit": ["MISFIT_FLOOR_PX", "MISFIT_RATIO", "check_misfit", "lattice_noise_px"],
        "pinned": ["MAX_SCALE_SIGMA", "check_scale_pinned"],
        "refit": ["REFIT_PARAMS", "Refit", "combination_text", "refit_rig"],
        "report": ["write_report"],
        "sweep": ["calibrate_sweep", "dumps_sweep"],
        "synthetic": ["check_card_fits", "random_poses", "render_grid_shots"],
        "tare": ["MIN_TARE_SIGMA_MM", "SCALE_PINNED", "TARE_SIGMA_MM", "Tare", "tare_plane", "tares_scale_sigma"],
    },
)
