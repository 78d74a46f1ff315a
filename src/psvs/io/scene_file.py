"""Scene files (TOML) -> :class:`psvs.simulate.scene.Scene`. Format: docs/scene_file.md.

Lengths in mm, angles in degrees (``rotation_deg``: extrinsic x-y-z Euler angles). Texture and mesh
files are relative to the scene file. Every error names the file, the object and the key.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from psvs.io.images import read_grey
from psvs.io.schema import check_keys
from psvs.io.text import input_file
from psvs.io.tomlfile import load_toml
from psvs.simulate import textures as tx
from psvs.simulate.scene import KINDS, Lighting, Pose, Scene, SceneObject, check_object_count

_OBJECT_KEYS = {"type", "name", "position_mm", "rotation_deg", "albedo", "texture", "size_mm", "radius_mm",
                "height_mm", "file", "scale"}
_TEXTURES = {
    "uniform": (tx.Uniform, {"albedo"}),
    "checker": (tx.Checker, {"square_mm", "low", "high"}),
    "noise": (tx.Noise, {"scale_mm", "seed", "low", "high"}),
    "circles": (tx.Circles, {"diameter_mm", "spacing_mm", "count", "low", "high"}),
    "chessboard": (tx.Chessboard, {"squares_x", "squares_y", "square_mm", "low", "high"}),
    "circle_grid": (tx.CircleGrid, {"rows", "cols", "spacing_mm", "diameter_mm", "low", "high"}),
    "image": (None, {"file", "size_mm"}),
}


def load_scene(path) -> Scene:
    """Read a scene file; raise ValueError/FileNotFoundError naming the file and the problem."""
    path = Path(path)
    data = load_toml(path, "scene")
    try:
        return scene_from_dict(data, base=path.parent, name=path.stem)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        raise type(exc)(f"{path}: {exc}") from None


def _vec(value, n: int, where: str) -> np.ndarray:
    if not isinstance(value, (list, tuple)) or len(value) != n or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise ValueError(f"{where} must be a list of {n} numbers, got {value!r}")
    return np.asarray(value, dtype=float)


def _texture(spec, where: str, base: Path, object_size) -> tx.Texture:
    if not isinstance(spec, dict) or "type" not in spec:
        raise ValueError(f"{where} must be a table with a 'type' ({', '.join(_TEXTURES)}), got {spec!r}")
    kind = spec["type"]
    if kind not in _TEXTURES:
        raise ValueError(f"{where}: unknown texture type {kind!r} (known: {', '.join(_TEXTURES)})")
    cls, allowed = _TEXTURES[kind]
    params = {k: v for k, v in spec.items() if k != "type"}
    check_keys(params, where, optional=tuple(sorted(allowed)), what=f"{kind} texture")
    if kind != "image":
        return cls(**params)
    if "file" not in params:
        raise ValueError(f"{where}: an image texture needs 'file'")
    file = input_file(base / params["file"], f"{where}: texture file")
    try:
        img = read_grey(file)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    size = params.get("size_mm", object_size)
    if size is None:
        raise ValueError(f"{where}: give size_mm for an image texture on a non-rectangular object")
    return tx.ImageTexture(img.astype(float) / 255.0, tuple(_vec(size, 2, f"{where}.size_mm")), str(file))


def _mesh(file: Path, where: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (N, 3), triangles (M, 3)) of a mesh file read by trimesh; ValueError naming ``where`` and the
    file when trimesh cannot read it or it holds no triangles.

    trimesh's loaders fail in their own ways -- NotImplementedError for a type it does not know (a PNG),
    ValueError, IndexError or KeyError from inside a damaged file's parser, or a missing optional
    package -- so every error but the machine's own (memory, the file system) means "not a mesh"."""
    import trimesh
    try:
        mesh = trimesh.load(file, force="mesh")
        vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    except (MemoryError, OSError):
        raise
    except Exception as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"{where}: not a mesh trimesh can read (STL, OBJ, PLY, ...): {file} ({reason})") from None
    if faces.ndim != 2 or faces.shape[1] != 3 or not len(faces):
        raise ValueError(f"{where}: {file} holds no triangles")
    return vertices, faces


def _object(spec: dict, i: int, base: Path) -> SceneObject:
    if not isinstance(spec, dict):
        raise ValueError(f"objects[{i}] must be a table, got {type(spec).__name__}")
    label = f"objects[{i}]" + (f" ({spec['name']})" if "name" in spec else "")
    check_keys(spec, f"objects[{i}]", optional=tuple(sorted(_OBJECT_KEYS)))
    kind = spec.get("type")
    if kind not in KINDS:
        raise ValueError(f"{label}: unknown primitive {kind!r} (known: {', '.join(KINDS)})")
    pose = Pose.from_euler_deg(_vec(spec.get("position_mm", [0, 0, 0]), 3, f"{label}.position_mm"),
                               _vec(spec.get("rotation_deg", [0, 0, 0]), 3, f"{label}.rotation_deg"))
    kw = {"name": str(spec.get("name", ""))}
    if "size_mm" in spec:
        n = 2 if kind == "rectangle" else 3
        kw["size_mm"] = tuple(float(v) for v in _vec(spec["size_mm"], n, f"{label}.size_mm"))
    for key in ("radius_mm", "height_mm"):
        if key in spec:
            kw[key] = spec[key]
    if kind == "mesh":
        if "file" not in spec:
            raise ValueError(f"{label}: a mesh needs 'file' (STL, OBJ, PLY, ...)")
        file = input_file(base / spec["file"], f"{label}: mesh file")
        vertices, kw["faces"] = _mesh(file, f"{label}.file")
        kw["vertices_mm"] = vertices * float(spec.get("scale", 1.0))
    albedo = spec.get("albedo", 0.8)
    texture = _texture(spec["texture"], f"{label}.texture", base, kw.get("size_mm") if kind == "rectangle" else None) \
        if "texture" in spec else tx.Uniform(albedo)
    try:
        return SceneObject(kind, pose, texture, **kw)
    except (ValueError, TypeError) as exc:
        raise type(exc)(f"{label}: {exc}") from None


def scene_from_dict(data: dict, base: Path = Path("."), name: str = "") -> Scene:
    """Build a Scene from a scene file's dict; ``base`` resolves texture and mesh paths."""
    check_keys(data, "", optional=("name", "lighting", "backdrop", "objects"))
    objects = data.get("objects", [])
    if not isinstance(objects, list):
        raise ValueError("objects must be an array of tables ([[objects]])")
    check_object_count(len(objects))       # before any object is made
    objs = tuple(_object(spec, i, base) for i, spec in enumerate(objects))
    light = data.get("lighting", {})
    check_keys(light, "lighting", optional=("ambient", "lamp", "lamp_position_mm", "reference_mm", "shadows"))
    if "lamp_position_mm" in light:
        light = dict(light, lamp_position_mm=tuple(_vec(light["lamp_position_mm"], 3, "lighting.lamp_position_mm")))
    lighting = Lighting(**light)
    back = data.get("backdrop")
    z, texture = None, tx.Uniform(0.2)
    if back is not None:
        if set(back) - {"z_mm", "albedo", "texture"} or "z_mm" not in back:
            raise ValueError(f"backdrop needs z_mm (and optional albedo or texture), got keys {sorted(back)}")
        z = back["z_mm"]
        texture = _texture(back["texture"], "backdrop.texture", base, None) if "texture" in back \
            else tx.Uniform(back.get("albedo", 0.2))
    return Scene(objs, lighting, z, texture, str(data.get("name", name)))
