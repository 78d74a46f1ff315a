"""The welding cell's fixed geometry: the arm's home pose, the torch on the flange, the PSVS on the torch.

Tool frame T (the torch): z along the torch axis toward the work, x the direction of travel. The torch has
a 45 deg bent neck (common on welding torches): with the torch vertical the PUMA's wrist stays ~50 deg
away from its q5 = 0 singularity. The PSVS rides ahead of the torch: its frame C has Z along the torch
axis, Y (image rows) along the travel, so the seam crosses the image rows (the epipolar lines) and the
twins are found row by row, and its optical axis meets the work ``look_ahead_mm`` ahead of the torch tip.
"""
from __future__ import annotations

import numpy as np

from psvs.transforms import concat, transform_from, transform_from_rotvec, translation

#: A PUMA 560 configuration (right arm, elbow up) with the torch down over the table; IK starts here.
HOME_Q = np.radians([23.0, 4.5, -168.0, -54.0, -53.0, 161.0])

#: Torch on the flange: 100 mm along the flange's z, a 45 deg bend about y, then 200 mm to the tip.
NECK_MM, BEND_RAD, TORCH_MM = 100.0, np.pi / 4, 200.0


def tool2flange() -> np.ndarray:
    """The torch tip (tool frame T) in the flange frame, (4, 4) mm."""
    return concat(translation((0, 0, TORCH_MM)), transform_from_rotvec((0.0, BEND_RAD, 0.0), np.zeros(3)),
                  translation((0, 0, NECK_MM)))


def cam2tool(look_ahead_mm: float, standoff_mm: float, camera_distance_mm: float) -> np.ndarray:
    """Nominal PSVS mounting (the bracket drawing): frame C in the tool frame, (4, 4) mm. C's X = -y_T,
    Y = x_T (travel), Z = z_T (torch axis); its centre ``look_ahead_mm`` ahead of the tip and
    ``camera_distance_mm`` above the work when the tip is ``standoff_mm`` above it."""
    R = np.column_stack([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    return transform_from(R, (look_ahead_mm, 0.0, standoff_mm - camera_distance_mm))


#: How the real bracket differs from its drawing (the simulated hardware; hand-eye calibration finds it):
#: a rotation vector (rad) and an offset (mm) applied in frame C.
MOUNT_ERROR = transform_from_rotvec([0.006, -0.004, 0.008], (0.8, -0.5, 1.2))


def tool_pose(position_mm, travel) -> np.ndarray:
    """tool2base (4, 4): the torch vertical (z_T = -z_base) at ``position_mm``, x_T along the horizontal
    part of ``travel``."""
    x = np.array([travel[0], travel[1], 0.0])
    x /= np.linalg.norm(x)
    z = np.array([0.0, 0.0, -1.0])
    return transform_from(np.column_stack([x, np.cross(z, x), z]), position_mm)
