"""One rule for every answer psvs gives: it is right, or it says why it cannot be (docs/right-or-refuse.md).

Each kind of answer states its evidence against a null, in one place per kind:

* **A fit** (a calibration, a hand-eye mount, the refraction terms): its residual against the residual its
  inputs' noise leaves at its solution (psvs.robot.handeye_noise for the hand-eye mount,
  psvs.measure.refraction_fit for the refraction terms), its fitted values against what the thing fitted can be
  (:func:`lens_problems`, :func:`build_problems`), and its conditioning on *distinct* evidence
  (:func:`distinct_rows`: a repeated row adds nothing, so a limit cannot grow with copies).
* **A match or a lock** (dense depth, edge pairs, tracking): beyond what chance makes on the same image
  (psvs.dense.echo_test for dense depth, psvs.match.chance for edge twins and the tracker's first lock).
* **A measurement of a known target**: what it knows of the target (spacing, diameters) against what it
  measured, within the measurement's noise (psvs.accuracy.pattern_measure).

A refusal is a :class:`psvs.errors.MeasurementError` (exit status 1) naming the figure, its limit and what
would explain the gap. This module sits beside psvs.optics, under every package that fits or measures: it
reads a rig's values by name and imports nothing of psvs but its errors.
"""
from __future__ import annotations

import math

import numpy as np

from psvs.errors import MeasurementError

#: px RMS: how far off their rows a calibration may leave the twins of ordinary frames and still be the rig's
#: (the self-check's default tolerance, psvs.health.check; the alignment guide's, psvs.mount.guide).
ROW_TOLERANCE_PX = 0.5
#: The largest radial distortion a lens of the field has at the image's corner, as a share of the radius
#: (machine-vision 6-25 mm lenses stay under 5 %; 25 % is a fisheye, which psvs's model does not cover).
MAX_CORNER_DISTORTION = 0.25
#: rad: the largest mirror tilt off its design a build can have and still be the design (a glued or
#: screwed mirror is set within tenths of a degree; 2 degrees moves a view by a tenth of its field).
MAX_BUILD_TILT_RAD = math.radians(2.0)
#: The largest share a calibrated focal length may differ from the design's (a stock lens's tolerance is
#: 5 %; more is another lens).
MAX_FOCAL_CHANGE = 0.15
#: The largest share a calibrated baseline may differ from the design's: a build's glass seated within
#: 0.2 deg and 0.5 mm moves its virtual cameras by up to 4.5 % of the paper's 100 mm (psvs adjust's limit,
#: psvs.mount.report); more is another design, or a card printed at another scale (a calibration cannot
#: tell a card 10 % larger from a world 10 % smaller: only the design's baseline can).
MAX_BASELINE_CHANGE = 0.05
#: The farthest a calibrated principal point may lie from the design's (a sensor window's own, or the image's
#: centre), as a share of the image's width and height (a lens centred on its sensor by its mount: within a few
#: per cent; 10 % is a lens knocked off its axis, or a fit that put the centre where two builds' views disagree).
MAX_PRINCIPAL_OFFSET = 0.10
MIRRORS = ("m1", "m2", "m3", "m4")


def distinct_rows(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """The rows of ``arrays`` (each (N, k), same N) with every exact repeat of a whole row (across all the
    arrays together) removed, in order of first appearance: a repeated observation adds no evidence."""
    if not arrays:
        return ()
    n = len(arrays[0])
    joined = np.concatenate([np.asarray(a, dtype=np.float64).reshape(n, -1) for a in arrays], axis=1)
    _, first = np.unique(joined, axis=0, return_index=True)
    keep = np.sort(first)
    return tuple(np.asarray(a)[keep] for a in arrays)


def lens_problems(camera) -> list[str]:
    """What a real lens of the field cannot have in ``camera``'s fitted distortion (OpenCV's k1, k2, p1, p2,
    k3): the radial mapping r (1 + k1 r^2 + k2 r^4 + k3 r^6) must grow over the whole image (a fold sends
    two directions to one pixel) and move the corner by at most :data:`MAX_CORNER_DISTORTION` of its radius."""
    k1, k2, _, _, k3 = camera.distortion
    w, h = camera.image_size_px
    cx, cy = camera.principal_point_px
    px, py = camera.pixel_pitch_mm
    f = camera.focal_length_mm
    corner = max(math.hypot(max(cx, w - 1 - cx) * px, max(cy, h - 1 - cy) * py) / f, 1e-9)
    r = np.linspace(0.0, corner, 256)
    radial = 1.0 + k1 * r ** 2 + k2 * r ** 4 + k3 * r ** 6
    slope = 1.0 + 3 * k1 * r ** 2 + 5 * k2 * r ** 4 + 7 * k3 * r ** 6
    problems = []
    if np.any(slope <= 0):
        problems.append(f"the lens's fitted distortion (k1 {k1:.3g}, k2 {k2:.3g}, k3 {k3:.3g}) folds the image "
                        f"back at {r[np.argmax(slope <= 0)] * f:.2f} mm from the centre: no lens does that")
    elif abs(radial[-1] - 1.0) > MAX_CORNER_DISTORTION:
        problems.append(f"the lens's fitted distortion (k1 {k1:.3g}, k2 {k2:.3g}, k3 {k3:.3g}) moves the image's "
                        f"corner by {abs(radial[-1] - 1.0):.0%} of its radius (a lens of the field: under "
                        f"{MAX_CORNER_DISTORTION:.0%})")
    return problems


def build_problems(fitted, design, baseline: bool = True) -> list[str]:
    """What a build of ``design`` cannot be in the rig ``fitted`` (both psvs.optics.rig.Rig): a mirror
    tilted more than :data:`MAX_BUILD_TILT_RAD` off its design, a baseline more than
    :data:`MAX_BASELINE_CHANGE` off the design's (only with ``baseline``: where the fit's scale rests on a card's
    printed size; a robot's steps measure it), a focal length more than
    :data:`MAX_FOCAL_CHANGE` off the design's, a principal point more than :data:`MAX_PRINCIPAL_OFFSET` of the
    image from the design's, a lens no lens is (:func:`lens_problems`). (The plate's thickness is not judged: a
    start rig may guess it, and the views pin it.)"""
    problems = []
    for m in MIRRORS:
        tilt = getattr(fitted.mirrors, f"{m}_error").tilt_rad
        worst = max(abs(t) for t in tilt)
        if worst > MAX_BUILD_TILT_RAD:
            problems.append(f"{m.upper()} fitted {math.degrees(worst):.2f} deg off its design (a build of it: "
                            f"under {math.degrees(MAX_BUILD_TILT_RAD):.0f} deg)")
    b0, b1 = design.mirrors.baseline_mm, fitted.mirrors.baseline_mm
    if baseline and abs(b1 / b0 - 1.0) > MAX_BASELINE_CHANGE:
        problems.append(f"baseline fitted {b1:.2f} mm against the design's {b0:.2f} mm (a build of it: within "
                        f"{MAX_BASELINE_CHANGE:.0%}; a card printed at another scale than its target file says "
                        "scales the whole rig)")
    f0, f1 = design.camera.focal_length_mm, fitted.camera.focal_length_mm
    if abs(f1 / f0 - 1.0) > MAX_FOCAL_CHANGE:
        problems.append(f"focal length fitted {f1:.3g} mm against the design's {f0:.3g} mm (a stock lens: within "
                        f"{MAX_FOCAL_CHANGE:.0%})")
    (w, h), fit, own = fitted.camera.image_size_px, fitted.camera.principal_point_px, design.camera.principal_point_px
    for axis, c, c0, size in (("cx", fit[0], own[0], w), ("cy", fit[1], own[1], h)):
        if abs(c - c0) > MAX_PRINCIPAL_OFFSET * size:
            problems.append(f"principal point {axis} fitted {c:.1f} px, {abs(c - c0):.0f} px from the design's "
                            f"{c0:.1f} (a lens on its mount: within {MAX_PRINCIPAL_OFFSET:.0%} of the image, "
                            f"{MAX_PRINCIPAL_OFFSET * size:.0f} px)")
    return problems + lens_problems(fitted.camera)


def check_build(fitted, design, what: str, baseline: bool = True) -> None:
    """MeasurementError naming every implausible value of :func:`build_problems` (nothing is written)."""
    problems = build_problems(fitted, design, baseline)
    if problems:
        raise MeasurementError(f"{what} gives a rig no build of the design can be: " + "; ".join(problems)
                               + ": the images are of another rig, or of several")
