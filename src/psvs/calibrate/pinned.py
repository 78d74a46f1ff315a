"""Whether a calibration's views pin its scale (docs/right-or-refuse.md, docs/calibration.md).

A narrow lens's focal length and every distance scale together: cards held square to the camera are seen the
same through f and a card at Z as through k f and one at about k Z, with the lens's distortion terms scaled to
match (k1 by k^2, k2 by k^4, ...). Only what breaks that (a card tilted, so that its near and far edges lie at
different depths; a robot sweep's known steps) pins f. Where the views do not, the fit still ends somewhere in
the valley, and every depth through the rig is then off by as much as f: an adversarial trial's ten cards held
square at 470-980 mm wrote f 2.6 % short (its cost 0.2 chi-square from the truth's), and depths read 2.6-2.9 %
short. The bundle adjustment's covariance (:func:`psvs.calibrate.bundle.covariance`) states that freedom; a
calibration whose f it leaves uncertain beyond :data:`MAX_SCALE_SIGMA` is refused, since no depth through it
would be worth one.
"""
from __future__ import annotations

from psvs.errors import MeasurementError

__all__ = ["MAX_SCALE_SIGMA", "check_scale_pinned"]

#: The largest 1-sigma of the focal length (a fraction of it) a calibration may leave: every depth through the
#: rig carries it. Cards tilted +-25 deg pin it to 0.13-0.2 %, three views 0.35 %; the same cards tilted only
#: +-6 deg at one distance 1.3 %, held square 3.3-5.5 % (their f 1.2 % and 2.6-3.2 % off).
MAX_SCALE_SIGMA = 0.01


def check_scale_pinned(bundle, what: str) -> None:
    """MeasurementError when the ``bundle``'s (:class:`psvs.calibrate.bundle.BundleResult`) focal length is
    uncertain beyond :data:`MAX_SCALE_SIGMA` of itself (module docstring); ``what`` names the calibration."""
    f, sigma = bundle.values["focal_length_mm"], bundle.sigma["focal_length_mm"]
    if sigma > MAX_SCALE_SIGMA * f:
        raise MeasurementError(
            f"{what} does not pin the focal length, and every length and depth scales with it: f {f:.3f} +- "
            f"{sigma:.3f} mm ({100 * sigma / f:.1f} %, beyond {100 * MAX_SCALE_SIGMA:g} %): cards held square to "
            "the camera leave f and their distances free together; hold the card tilted 20-25 deg each way, at "
            "several distances")
