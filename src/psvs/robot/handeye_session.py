"""The hand-eye session in the simulated cell: a circle grid on the table shown to the PSVS from several
flange poses, rendered with the true mounting and calibrated with what the sensor knows of the rig
(psvs.robot.handeye).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from psvs.optics.rig import Rig
from psvs.robot.arm import Arm
from psvs.robot.controller import TrackConfig
from psvs.robot.handeye import HandEyeResult, calibrate_from_views
from psvs.robot.mounting import HOME_Q, MOUNT_ERROR, cam2tool, tool2flange
from psvs.simulate.render import render
from psvs.simulate.scene import Lighting, Pose, Scene, SceneObject
from psvs.simulate.sequence import scene_in_rig_frame
from psvs.simulate.textures import CircleGrid
from psvs.transforms import concat, invert_transform, transform_from

#: The hand-eye session's target: a 4 x 5 circle grid lying face up on the table.
CELL_GRID = CircleGrid(rows=4, cols=5, spacing_mm=15.0, diameter_mm=7.0)
CELL_TARGET2BASE = transform_from(np.diag([1.0, -1.0, -1.0]), (550.0, 0.0, 0.0))
#: The session's views by default, and the samples per pixel side each is rendered with.
CELL_VIEWS = 12
CELL_SUPERSAMPLE = 1


def cell_lighting(cfg: TrackConfig) -> Lighting:
    """The PSVS's own lamp, regulated for the camera distance, over some ambient light."""
    return Lighting(ambient=0.25, lamp=0.75, reference_mm=cfg.camera_distance_mm)


def nominal_cam2flange(cfg: TrackConfig) -> np.ndarray:
    """Frame C on the flange as the bracket drawing has it (4, 4) mm."""
    return concat(cam2tool(cfg.look_ahead_mm, cfg.standoff_mm, cfg.camera_distance_mm), tool2flange())


def true_cam2flange(cfg: TrackConfig) -> np.ndarray:
    """Frame C on the flange as the simulated hardware really has it: the drawing and the bracket's
    error (:data:`psvs.robot.mounting.MOUNT_ERROR`); what a hand-eye calibration should find."""
    return concat(MOUNT_ERROR, nominal_cam2flange(cfg))


def cell_views(true_rig: Rig, cfg: TrackConfig, arm: Arm,
               views: int = CELL_VIEWS, grid: CircleGrid = CELL_GRID) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The hand-eye session in the simulated cell: ``grid`` (:data:`CELL_GRID`) on the table shown to the PSVS from
    ``views`` flange poses (tilted up to ~20 deg, turned about the vertical), rendered through ``true_rig``
    (the rig as built) with the true mounting. Returns (complex images (H, W) uint8, flange2base (4, 4))."""
    if not isinstance(views, int) or views < 3:
        raise ValueError(f"the hand-eye session needs an integer >= 3 views, got {views!r}")
    plate = SceneObject("rectangle", Pose(CELL_TARGET2BASE[:3, :3], CELL_TARGET2BASE[:3, 3]), grid,
                        size_mm=(320.0, 320.0), name="target")
    scene = Scene((plate,), cell_lighting(cfg), None)
    nominal, true = nominal_cam2flange(cfg), true_cam2flange(cfg)
    rng = np.random.default_rng(7)
    images, flanges = [], []
    for k in range(views):
        yaw = np.pi / 2 + (k - (views - 1) / 2) * 0.05
        tilt = Rotation.from_rotvec(np.append(rng.uniform(-0.35, 0.35, 2), yaw)).as_matrix()
        cam_R = tilt @ np.diag([1.0, -1.0, -1.0])   # camera looking down, turned and tilted
        cam_pos = CELL_TARGET2BASE[:3, 3] - cfg.camera_distance_mm * cam_R[:, 2] + \
            np.append(rng.uniform(-10, 10, 2), 0)
        flange = concat(invert_transform(nominal), transform_from(cam_R, cam_pos))
        F = arm.fkine(arm.ikine(flange, HOME_Q))
        img = render(scene_in_rig_frame(scene, invert_transform(concat(true, F))), true_rig,
                     supersample=CELL_SUPERSAMPLE, seed=100 + k).image
        images.append(img)
        flanges.append(F)
    return images, flanges


def calibrate_cell(rig: Rig, cfg: TrackConfig, arm: Arm, views: int = CELL_VIEWS,
                   true_rig: Rig | None = None) -> tuple[HandEyeResult, np.ndarray]:
    """Hand-eye calibration session in the simulated cell (:func:`cell_views`, rendered through
    ``true_rig``, default ``rig``), calibrated with ``rig``, what the sensor knows of the rig; returns the
    result and the true cam2flange of the simulated hardware."""
    images, flanges = cell_views(true_rig or rig, cfg, arm, views)
    he = calibrate_from_views(images, flanges, rig, CELL_GRID, nominal_cam2flange(cfg), CELL_TARGET2BASE)
    return he, true_cam2flange(cfg)
