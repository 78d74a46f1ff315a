"""Issue 7, one core: the seam sensor's stage of one control cycle (32-row window of the complex image:
both groove edges matched with their twins, sub-pixel, exact triangulation, groove-root fit) <= 10 ms."""
import cv2
import numpy as np

from psvs import default_rig
from psvs.robot.arm import Arm
from psvs.robot.cell import MOUNT_ERROR, cam2tool, tool2flange, tool_pose
from psvs.robot.loop import HOME_Q, UP, TrackConfig
from psvs.robot.sensor import SeamSensor, auto_seed, fit_seam_point, roi_rig
from psvs.robot.workpiece import seam_workpiece
from psvs.simulate.render import render
from psvs.simulate.sequence import scene_in_rig_frame

cv2.setNumThreads(1)


def _sensor_stage():
    cfg = TrackConfig()
    wp = seam_workpiece("weld_seam", cfg.camera_distance_mm)
    x0 = wp.x_range_mm[0] + cfg.start_offset_mm
    p0, p1 = wp.seam_base([x0, x0 + 1.0])
    arm = Arm(HOME_Q)
    arm.q = arm.ikine(tool_pose(p0 + cfg.standoff_mm * UP, p1 - p0) @ np.linalg.inv(tool2flange()), HOME_Q)
    cam = arm.fkine() @ tool2flange() @ cam2tool(cfg.look_ahead_mm, cfg.standoff_mm, cfg.camera_distance_mm) \
        @ MOUNT_ERROR
    roi, _ = roi_rig(default_rig(), cfg.roi_rows)
    img = render(scene_in_rig_frame(wp.scene, np.linalg.inv(cam)), roi, seed=1).image
    seed = auto_seed(img)

    def run():
        sensor = SeamSensor(roi, seed, 220.0, 420.0)
        obs = sensor.measure(img)
        a, b = (e @ cam[:3, :3].T + cam[:3, 3] for e in obs.edges_mm)
        fit_seam_point(a, b, cfg.groove_depth_mm, UP)
    return run


def cases():
    return [("seam sensor stage per control cycle (640x32 window, 2 edges)", _sensor_stage, 0.010)]
