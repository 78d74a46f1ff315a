"""How many pixels an angle spans on a camera, relative to the paper's: the scale of pixel tolerances.

A search window, a jump limit or a line tolerance in px is a size in the image, so it is really an angle
(or, at a depth, a length): tuned on the paper's camera (f = 11.3 mm on 10 um pixels: 1130 px per unit of
tan(angle)), it must grow with a camera whose pixels see a smaller angle. ``pixel_scale`` is that ratio
(f / pitch) / 1130: 1.0 for the paper's camera, 2.05 for mv1440's 8 mm lens on 3.45 um pixels.
"""
from __future__ import annotations

from psvs.optics.rig import Camera

#: The paper's camera (PULNIX TM-520 behind an 11.3 mm lens, 10 um pixels), px per unit tan(angle): the
#: camera psvs's pixel tolerances were tuned on.
PAPER_FOCAL_PX = 1130.0


def pixel_scale(camera: Camera) -> float:
    """(f / pitch_x) / :data:`PAPER_FOCAL_PX`: how many of the camera's pixels one paper pixel's angle spans.

    Examples
    --------
    >>> from psvs.optics.rig import Camera
    >>> round(pixel_scale(Camera()), 12), round(pixel_scale(Camera(8.0, (0.00345, 0.00345), (1440, 1080),
    ...                                                                (719.5, 539.5))), 4)
    (1.0, 2.0521)
    """
    return camera.focal_length_mm / camera.pixel_pitch_mm[0] / PAPER_FOCAL_PX
