"""Simulated live sequences: a scene seen by a rig that moves back and forth, rendered through the exact
optics (psvs.simulate.render), with fresh sensor noise on every frame.

Each distinct rig position is rendered once (its irradiance) and every frame is exposed with its own noise
seed, so long sequences (a 30 s video at 30 frames/s) cost only as many renders as distinct positions.
"""
from __future__ import annotations

import numpy as np

from psvs.io.atomic import write_atomic
from psvs.optics.rig import Rig
from psvs.simulate.builtin import regulated_light
from psvs.simulate.render import render
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.sensor import Sensor, expose
from psvs.simulate.sequence import scene_in_rig_frame
from psvs.simulate.textures import Uniform
from psvs.transforms import translation


def disc_scene(z_mm: float = 700.0, radius_mm: float = 30.0, x_mm: float = 0.0, y_mm: float = 0.0) -> Scene:
    """A bright fronto-parallel disc (albedo 0.9) at (x, y, z) mm on a dark backdrop 500 mm behind it. Every
    point of its rim lies at depth z: the truth of a tracked rim edge is the disc's z."""
    disc = SceneObject("disc", Pose(np.eye(3), np.array([x_mm, y_mm, z_mm], float)), Uniform(0.9),
                       radius_mm=radius_mm, name="disc")
    return Scene((disc,), regulated_light(z_mm), z_mm + 500.0, Uniform(0.08), "disc")


def ping_pong_positions(frames: int, move_mm, distinct: int) -> np.ndarray:
    """(frames, 3) rig positions (mm) going from 0 to ``move_mm`` and back, over ``distinct`` evenly spaced
    positions (a triangle wave of period 2 (distinct - 1) frames)."""
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames!r}")
    if distinct < 2:
        raise ValueError(f"distinct must be >= 2, got {distinct!r}")
    period = 2 * (distinct - 1)
    k = np.arange(frames) % period
    idx = np.where(k < distinct, k, period - k)
    return np.outer(idx / (distinct - 1), np.asarray(move_mm, float))


class SimulatedSequence:
    """Frames (H, W) uint8 of ``scene`` seen by ``rig`` displaced to ``positions_mm[k]`` (N, 3) for frame k.

    Frame k is exposed with noise seed ``seed + k``; renders are cached per distinct position. Index it,
    iterate it, take ``len``, or play it in a loop with :meth:`frame`.
    """

    def __init__(self, scene: Scene, rig: Rig, positions_mm, *, supersample: int = 1, sensor: Sensor = Sensor(),
                 seed: int = 0):
        pos = np.asarray(positions_mm, float)
        if pos.ndim != 2 or pos.shape[1] != 3 or len(pos) == 0:
            raise ValueError(f"positions_mm must have shape (N, 3), got {pos.shape}")
        self.scene, self.rig, self.positions_mm = scene, rig, pos
        self.supersample, self.sensor, self.seed = supersample, sensor, seed
        self._irradiance: dict[tuple, np.ndarray] = {}

    def __len__(self) -> int:
        return len(self.positions_mm)

    def irradiance(self, k: int) -> np.ndarray:
        """Frame ``k``'s irradiance (H, W) before the sensor, rendered once per distinct rig position and kept."""
        key = tuple(np.round(self.positions_mm[k], 9))
        if key not in self._irradiance:
            scene = scene_in_rig_frame(self.scene, translation(-self.positions_mm[k]))
            res = render(scene, self.rig, supersample=self.supersample, sensor=self.sensor, seed=None)
            self._irradiance[key] = res.irradiance
        return self._irradiance[key]

    def frame(self, k: int) -> np.ndarray:
        """Frame k >= 0 of the sequence played in a loop: position k mod N, noise seed ``seed + k``."""
        if k < 0:
            raise IndexError(f"frame index must be >= 0, got {k}")
        return expose(self.irradiance(k % len(self)), self.sensor, self.seed + k)

    def __getitem__(self, k: int) -> np.ndarray:
        if not 0 <= k < len(self):
            raise IndexError(f"frame {k} is outside the {len(self)}-frame sequence")
        return self.frame(k)

    def __iter__(self):
        for k in range(len(self)):
            yield self.frame(k)


def write_truth_csv(path, depth_mm) -> None:
    """``frame,depth_mm`` rows: the true depth of the tracked edge in every frame."""
    rows = "".join(f"{k},{z:.6f}\n" for k, z in enumerate(np.asarray(depth_mm, float)))
    write_atomic(path, "frame,depth_mm\n" + rows)
