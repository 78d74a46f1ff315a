"""What the twins' rows cannot show (docs/health.md, "What frames can show"): a mirror turned *about the
vertical* moves its view along its rows, not across them, and so does a focal length, a pixel pitch or a
baseline gone wrong (depth is f b / d: a baseline 10 % long reads every depth about 10 % far). ``psvs check``
says healthy on the rows it judged; this module puts a figure on what it did not judge, so that a healthy
verdict is not read as a depth checked.

A mirror turned by t turns its view by 2 t. The twins' disparity d = f b / (Z - z_v) (f in px, b the baseline,
z_v the virtual cameras' Z, paper eq. 11 with the virtual cameras' offset behind O) then moves by f 2 t, and the
depth by dZ = 2 t (Z - z_v)^2 / b: a share 2 t (Z - z_v)^2 / (b Z) of it.
"""
from __future__ import annotations

import math

from psvs.optics.rig import Rig

#: rad: the turn about the vertical the line quotes: what knocks and creep do to a glued mirror (docs/health.md)
QUOTED_TURN_RAD = math.radians(0.1)


def depth_share_of_turn(rig: Rig, z_mm: float, turn_rad: float = QUOTED_TURN_RAD) -> float:
    """The share of the depth (a fraction, > 0) at ``z_mm`` (mm from O, on the axis) that one mirror of ``rig``
    turned by ``turn_rad`` about the vertical moves, without moving the twins' rows (module docstring)."""
    zv = rig.virtual_z_mm
    return 2.0 * abs(turn_rad) * (z_mm - zv) ** 2 / (rig.mirrors.baseline_mm * z_mm)


def not_checked_line(rig: Rig, far_mm: float) -> str:
    """One line on what a healthy check did not judge, with the depth a 0.1 deg turn moves at ``far_mm``."""
    share = depth_share_of_turn(rig, far_mm)
    return (f"not checked (the rows cannot show it): a mirror turned about the vertical, a focal length, a pixel "
            f"pitch or a baseline off, which move depth along the rows (a turn of "
            f"{math.degrees(QUOTED_TURN_RAD):g} deg: "
            f"{100.0 * share:.1f} % at {far_mm:g} mm); tares at two known distances (psvs refit --tare) or a "
            f"known length (psvs measure circles) check them (one tare only at its own distance)")
