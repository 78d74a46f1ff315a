"""The seam workpiece placed in the robot's base frame: the scene to render and the true seam to score.

The built-in ``weld_seam`` scene (:func:`psvs.simulate.builtin.weld_seam`) is defined in a camera frame.
Here its objects are re-posed so that the workpiece's local frame (x along the seam, y across, z up)
sits at ``local2base`` in the base frame (mm): a workpiece lying on the robot's table.
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

from psvs.simulate.builtin import parse_spec, seam_centre_line, weld_seam
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.transforms import concat, invert_transform

#: Where the workpiece lies: seam along base +y, 550 mm in front of the PUMA's base axis, on the table
#: (base z = 0, the shoulder is 672 mm above it).
DEFAULT_PLACEMENT = np.array([[0.0, -1.0, 0.0, 550.0],
                              [1.0, 0.0, 0.0, 0.0],
                              [0.0, 0.0, 1.0, 0.0],
                              [0.0, 0.0, 0.0, 1.0]])


@dataclass(frozen=True, eq=False)
class Workpiece:
    """The seam workpiece in the base frame.

    scene : Scene in the base frame (render it with :func:`psvs.simulate.sequence.scene_in_rig_frame`).
    params : the ``weld_seam`` parameters (radius_mm, length_mm, height_amplitude_mm, gap...).
    local2base : (4, 4) the workpiece's local frame in the base frame, mm.
    """

    scene: Scene
    params: dict
    local2base: np.ndarray

    def seam_local(self, x_mm) -> np.ndarray:
        """True seam (groove bottom) at local x positions, (N, 3) mm, workpiece frame."""
        p = self.params
        return seam_centre_line(x_mm, p["radius_mm"], p["length_mm"], p["height_amplitude_mm"])

    def seam_base(self, x_mm) -> np.ndarray:
        """True seam at local x positions, (N, 3) mm, base frame."""
        q = self.seam_local(x_mm)
        return q @ self.local2base[:3, :3].T + self.local2base[:3, 3]

    def in_gap(self, x_mm) -> np.ndarray:
        """(N,) bool: local x lies in the filled stretch (no groove)."""
        p = self.params
        x = np.asarray(x_mm, float)
        if p.get("gap_start_mm") is None:
            return np.zeros(x.shape, bool)
        return (x >= p["gap_start_mm"]) & (x <= p["gap_start_mm"] + p["gap_length_mm"])

    @property
    def x_range_mm(self) -> tuple[float, float]:
        half = self.params["length_mm"] / 2
        return -half, half


def seam_workpiece(spec: str = "weld_seam", camera_distance_mm: float = 300.0,
                   local2base: np.ndarray = DEFAULT_PLACEMENT) -> Workpiece:
    """The ``weld_seam[:key=value,...]`` scene placed in the base frame.

    ``camera_distance_mm`` sets the scene's lamp reference (full lamp irradiance at the sensor's working
    distance); a ``width_mm`` default of 320 mm keeps plate under both views (baseline 100 mm).
    """
    name, kwargs = parse_spec(spec)
    if name != "weld_seam":
        raise ValueError(f"psvs track needs a seam workpiece: scene must be 'weld_seam[:key=value,...]', got {name!r}")
    defaults = {k: v.default for k, v in inspect.signature(weld_seam).parameters.items()}
    params = {**defaults, "width_mm": 320.0, **kwargs, "distance_mm": float(camera_distance_mm)}
    if params["radius_mm"] <= 0 or params["length_mm"] <= 0:
        raise ValueError("weld_seam: radius_mm and length_mm must be > 0")
    if params.get("gap_start_mm") is not None and params["gap_length_mm"] < 0:
        raise ValueError(f"weld_seam: gap_length_mm must be >= 0, got {params['gap_length_mm']!r}")
    scene = weld_seam(**params)
    seam_pose = scene.objects[-1].pose.matrix          # local -> the scene's own frame
    scene2base = concat(invert_transform(seam_pose), local2base)
    objs = list(scene.objects)
    if scene.backdrop_z_mm is not None:   # the backdrop becomes the floor under the table: a 1.5 m square
        objs.append(SceneObject("rectangle", Pose(np.eye(3), np.array([0.0, 0.0, scene.backdrop_z_mm])),
                                scene.backdrop_texture, size_mm=(1500.0, 1500.0), name="floor"))
    moved = []
    for o in objs:
        T = concat(o.pose.matrix, scene2base)
        moved.append(type(o)(o.kind, Pose(T[:3, :3], T[:3, 3]), o.texture, o.size_mm, o.radius_mm, o.height_mm,
                             o.vertices_mm, o.faces, o.name))
    base_scene = Scene(tuple(moved), scene.lighting, None, scene.backdrop_texture, scene.name)
    return Workpiece(base_scene, params, np.asarray(local2base, float))
