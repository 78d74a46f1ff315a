"""Scenes: objects with poses, albedo textures, a backdrop and lighting (frame C, mm, radians).

Every object has a local frame; ``pose`` maps local points to frame C: p_C = R p_local + t. Flat
objects (rectangle, disc) lie in their local z = 0 plane and face -z, i.e. the camera, at the identity
rotation. Textures are functions of local (x, y) mm.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from psvs._validate import check_finite, check_positive
from psvs.simulate.textures import Texture, Uniform
from psvs.transforms import transform_from

KINDS = ("rectangle", "disc", "box", "cylinder", "sphere", "mesh")
#: mm: the largest size or distance of a primitive (10 km): a box of 1e20 mm vanished from the render and its
#: truth without a word.
MAX_SCENE_MM = 1e7


@dataclass(frozen=True, eq=False)
class Pose:
    """Rotation (3, 3) and translation (3,) mm from the object's local frame to frame C."""

    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    position_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def matrix(self) -> np.ndarray:
        """local2world (4, 4) mm: the pose as a homogeneous transform."""
        return transform_from(self.rotation, self.position_mm)

    def to_world(self, p_local: np.ndarray) -> np.ndarray:
        """Points (N, 3) mm from the object's own frame to the world (the rig's frame)."""
        return p_local @ self.rotation.T + self.position_mm

    def to_local(self, p_world: np.ndarray) -> np.ndarray:
        """Points (N, 3) mm from the world (the rig's frame) to the object's own frame."""
        return (p_world - self.position_mm) @ self.rotation

    @staticmethod
    def from_euler_deg(position_mm, rotation_deg) -> "Pose":
        """Pose from a position (mm) and extrinsic x-y-z Euler angles (degrees): R = Rz Ry Rx."""
        from scipy.spatial.transform import Rotation
        R = Rotation.from_euler("xyz", np.asarray(rotation_deg, dtype=float), degrees=True).as_matrix()
        return Pose(R, np.asarray(position_mm, dtype=float))


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One object.

    kind : 'rectangle' (size_mm = (w, h)), 'disc' (radius_mm), 'box' (size_mm = (x, y, z)),
           'cylinder' (radius_mm, height_mm along local z), 'sphere' (radius_mm), 'mesh' (vertices_mm,
           faces: a triangle mesh in local coordinates, e.g. loaded with trimesh).
    """

    kind: str
    pose: Pose
    texture: Texture = Uniform()
    size_mm: tuple[float, ...] = ()
    radius_mm: float = 0.0
    height_mm: float = 0.0
    vertices_mm: np.ndarray | None = None
    faces: np.ndarray | None = None
    name: str = ""

    def __post_init__(self):
        label = self.name or self.kind
        if self.kind not in KINDS:
            raise ValueError(f"unknown primitive {self.kind!r} (known: {', '.join(KINDS)})")
        if self.kind in ("rectangle", "box"):
            n = 2 if self.kind == "rectangle" else 3
            if len(self.size_mm) != n:
                raise ValueError(f"{label}: size_mm must have {n} values, got {self.size_mm!r}")
            for v in self.size_mm:
                check_positive(v, f"{label}: size_mm", "mm")
        if self.kind in ("disc", "cylinder", "sphere"):
            check_positive(self.radius_mm, f"{label}: radius_mm", "mm")
        if self.kind == "cylinder":
            check_positive(self.height_mm, f"{label}: height_mm", "mm")
        if self.kind == "mesh":
            if self.vertices_mm is None or self.faces is None or len(self.faces) == 0:
                raise ValueError(f"{label}: a mesh needs vertices and at least one face")
        if not np.all(np.isfinite(self.pose.position_mm)) or not np.all(np.isfinite(self.pose.rotation)):
            raise ValueError(f"{label}: pose must be finite")
        for what, values in (("size_mm", self.size_mm), ("radius_mm", (self.radius_mm,)),
                             ("height_mm", (self.height_mm,)), ("position", self.pose.position_mm)):
            if np.any(np.abs(np.asarray(values, dtype=float)) > MAX_SCENE_MM):
                shown = ", ".join(f"{float(v):g}" for v in np.ravel(np.asarray(values, dtype=float)))
                raise ValueError(f"{label}: {what} beyond {MAX_SCENE_MM:g} mm, got [{shown}] (the ray tracer's "
                                 "single precision loses such an object)")


@dataclass(frozen=True)
class Lighting:
    """Ambient light plus the rig's own lamp, a point source (Lambertian surfaces, inverse-square falloff).

    Irradiance on a surface with normal n at distance r from the lamp, direction l to the lamp:
    E = ambient + lamp * max(0, n . l) * (reference_mm / r)^2; radiance = albedo * E.
    """

    ambient: float = 0.35
    lamp: float = 0.65
    lamp_position_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    reference_mm: float = 600.0
    shadows: bool = True

    def __post_init__(self):
        if check_finite(self.ambient, "ambient") < 0 or check_finite(self.lamp, "lamp") < 0:
            raise ValueError(f"ambient and lamp must be >= 0, got {self.ambient!r}, {self.lamp!r}")
        check_positive(self.reference_mm, "reference_mm", "mm")


#: Most objects a scene may hold: each is shaded and refined on its own (a shape of many parts is one mesh).
MAX_OBJECTS = 1000


def check_object_count(n: int, limit: int = MAX_OBJECTS) -> None:
    """ValueError when ``n`` objects are more than a scene may hold (``limit``, :data:`MAX_OBJECTS`): checked
    before they are made."""
    if n > limit:
        raise ValueError(f"{n} objects, at most {limit} (a shape of many parts is one mesh object: its file "
                         "holds the triangles)")


@dataclass(frozen=True, eq=False)
class Scene:
    """Objects (at most :data:`MAX_OBJECTS`), an optional backdrop (a plane z = backdrop_z_mm facing the camera)
    and lighting."""

    objects: tuple[SceneObject, ...]
    lighting: Lighting = Lighting()
    backdrop_z_mm: float | None = None
    backdrop_texture: Texture = Uniform(0.2)
    name: str = ""

    def __post_init__(self):
        if self.backdrop_z_mm is not None:
            check_positive(self.backdrop_z_mm, "backdrop z_mm", "mm")
            if self.backdrop_z_mm > MAX_SCENE_MM:       # said here, in the scene file's words and name
                raise ValueError(f"backdrop z_mm must be at most {MAX_SCENE_MM:g} mm, got {self.backdrop_z_mm:g} "
                                 "(the ray tracer's single precision loses such a plane)")
        if not self.objects and self.backdrop_z_mm is None:
            raise ValueError("a scene needs at least one object or a backdrop")
        # one more than a user's scene may hold: psvs turns a scene's backdrop into an object of its own (a
        # moving sequence, the robot's cell) after the user's were counted
        check_object_count(len(self.objects), MAX_OBJECTS + 1)
