"""Image sequences along a camera (rig) trajectory: the scene stays put in the world, the rig moves."""
from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from psvs.optics.rig import Rig
from psvs.simulate.geometry import SceneGeometry, backdrop_object
from psvs.simulate.render import RenderResult, check_scene_in_front, render
from psvs.simulate.scene import Pose, Scene
from psvs.simulate.sensor import Sensor
from psvs.transforms import translation


def scene_in_rig_frame(scene: Scene, world2rig: np.ndarray) -> Scene:
    """The scene seen from a rig whose frame C is at ``world2rig`` (4x4: world points -> frame C).

    The backdrop becomes an ordinary (large) rectangle so that it moves with the world.
    """
    R, t = world2rig[:3, :3], world2rig[:3, 3]
    objs = list(scene.objects) + ([backdrop_object(scene)] if scene.backdrop_z_mm is not None else [])
    moved = tuple(
        type(o)(o.kind, Pose(R @ o.pose.rotation, R @ o.pose.position_mm + t), o.texture, o.size_mm, o.radius_mm,
                o.height_mm, o.vertices_mm, o.faces, o.name) for o in objs)
    return Scene(moved, scene.lighting, None, scene.backdrop_texture, scene.name)


def straight_path(start_mm, end_mm, frames: int) -> list[np.ndarray]:
    """``frames`` world2rig transforms for a rig translated from start to end (mm), orientation fixed."""
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames!r}")
    out = []
    for s in np.linspace(0.0, 1.0, frames):
        out.append(translation(-((1 - s) * np.asarray(start_mm, float) + s * np.asarray(end_mm, float))))
    return out


def render_sequence(scene: Scene, rig: Rig, world2rig: Iterable[np.ndarray], *, supersample: int = 2,
                    sensor: Sensor = Sensor(), seed: int = 0, truth: bool = False) -> Iterator[RenderResult]:
    """Render one frame per rig pose; frame i uses noise seed ``seed + i`` (reproducible). The scene's
    geometry is built once (:func:`render_from`), and every pose is checked before the first frame is
    rendered: ValueError naming the first frame whose scene reaches behind the rig (a move that carries the
    rig into it)."""
    geometry = SceneGeometry(scene)
    poses = [np.asarray(T, dtype=np.float64) for T in world2rig]
    for i, T in enumerate(poses):
        try:
            check_scene_in_front(geometry.moved(T, scene_in_rig_frame(scene, T).objects), rig)
        except ValueError as exc:
            raise ValueError(f"frame {i} of {len(poses)}: {exc}") from None
    for i, T in enumerate(poses):
        yield render_from(scene, T, rig, geometry, supersample=supersample, sensor=sensor, seed=seed + i,
                          truth=truth)


def render_from(scene: Scene, world2rig: np.ndarray, rig: Rig, geometry: SceneGeometry | None = None,
                **kwargs) -> RenderResult:
    """:func:`psvs.simulate.render.render` of ``scene`` seen from a rig at ``world2rig`` (4x4: world points ->
    frame C), i.e. of :func:`scene_in_rig_frame`, with ``geometry`` (``SceneGeometry(scene)``, built once for
    every pose of a moving rig) moved there instead of built for this pose. ``kwargs``: render's."""
    T = np.asarray(world2rig, dtype=np.float64)
    moved = scene_in_rig_frame(scene, T)
    return render(moved, rig, geometry=None if geometry is None else geometry.moved(T, moved.objects), **kwargs)
