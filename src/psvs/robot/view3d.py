"""What the PSVS on the arm sees at one cycle of a run: the rig's layout (the camera, its light through the four
glasses, both views' fields; :func:`psvs.optics.layout3d.rig_layout`) carried from frame C into the robot's
base frame through the arm's pose (the PUMA 560's forward kinematics at the cycle's joint angles) and the
camera's mounting on the flange (the run's hand-eye calibration). Drawn by the web page's Robot step beside the
seam and the torch's path."""
from __future__ import annotations

import numpy as np

from psvs.optics.layout3d import rig_layout
from psvs.optics.rig import Rig
from psvs.robot.kinematics import PUMA560


def cam2base(q_rad, cam2flange) -> np.ndarray:
    """Frame C in the robot's base frame (4, 4, mm) at joint angles ``q_rad`` (6,) with the camera mounted at
    ``cam2flange`` (4, 4, mm)."""
    return PUMA560.fkine(np.asarray(q_rad, float)) @ np.asarray(cam2flange, float)


def sensor_view(q_rad, cam2flange, rig: Rig, near_mm: float, far_mm: float) -> dict:
    """The rig's layout over ``near_mm``..``far_mm`` (:func:`psvs.optics.layout3d.rig_layout`: ``camera`` (3,),
    ``virtual`` {view: (3,)}, ``rays`` {view: [polyline (k, 3)]}, ``field`` {view: {near, far: (4, 3) or
    None}}) in the robot's base frame (mm) at joint angles ``q_rad`` (6,) and mounting ``cam2flange`` (4, 4)."""
    pose = cam2base(q_rad, cam2flange)
    rot, at = pose[:3, :3], pose[:3, 3]

    def move(p):
        return None if p is None else np.asarray(p, float) @ rot.T + at

    lay = rig_layout(rig, near_mm, far_mm)
    return {"camera": move(lay["camera"]), "virtual": {v: move(c) for v, c in lay["virtual"].items()},
            "rays": {v: [move(line) for line in lines] for v, lines in lay["rays"].items()},
            "field": {v: {k: move(f) for k, f in fs.items()} for v, fs in lay["field"].items()}}
