"""Built-in scenes that reproduce the paper's images, in frame C (mm, degrees in parameters).

fig5a      simple objects whose left and right views are separated (paper Fig. 5a)
fig5b      two ashtray-like objects whose views partly overlap (Fig. 5b)
fig6       a cluttered scene (Fig. 6)
fig9       the accuracy pattern: 5 circles of 10 mm, 20 mm apart, on a sheet (Fig. 9), at any distance/pose
weld_seam  two plates meeting along a curved, beveled seam (the arc-welding workpiece, psvs track)
textured   photo-textured objects and backdrop for dense disparity (docs/dense.md)
"""
from __future__ import annotations

import inspect
import math

import numpy as np

from psvs._validate import check_count
from psvs.simulate.scene import Lighting, Pose, Scene, SceneObject, check_object_count
from psvs.simulate.textures import Checker, Circles, ImageTexture, Noise, Uniform


def pose_at(x, y, z, rx=0.0, ry=0.0, rz=0.0) -> Pose:
    """An object's pose at (x, y, z) mm, turned by extrinsic x-y-z Euler angles rx, ry, rz in degrees, as scene
    files give them (:meth:`psvs.simulate.scene.Pose.from_euler_deg`)."""
    return Pose.from_euler_deg([x, y, z], [rx, ry, rz])


def regulated_light(distance_mm: float) -> Lighting:
    """The paper's "regulated lighting system on the apparatus": mostly even light with a mild lamp, so one
    view of a bright object (albedo >= 0.8) lands well above the paper's binary threshold 92 and the
    background (albedo <= 0.2) well below it, at every depth of the scene."""
    return Lighting(ambient=0.8, lamp=0.3, reference_mm=distance_mm)


def fig5a(distance_mm: float = 600.0) -> Scene:
    """A box and an upright cylinder at ~distance_mm whose left and right views do not overlap."""
    z = distance_mm
    objs = (
        SceneObject("box", pose_at(-60, -50, z, 0, 20, 0), Noise(6, 1, 0.8, 0.95), size_mm=(60, 60, 40), name="box"),
        SceneObject("cylinder", pose_at(60, 60, z + 50, 90, 0, 0), Uniform(0.9), radius_mm=25, height_mm=60,
                    name="cylinder"),
    )
    return Scene(objs, regulated_light(z), 2 * z, Uniform(0.1), "fig5a")


def fig5b(distance_mm: float = 700.0) -> Scene:
    """Two ashtray-like objects (short cylinders with a dark bowl) side by side; their views overlap.

    The two differ in size and depth: with two *identical* objects whose views overlap, swapping which
    copy belongs to which view gives the very same complex image, and no method can tell them apart.
    """
    z = distance_mm
    objs = []
    for name, x, dz, r, r_bowl in (("ashtray_left", -45.0, 0.0, 40.0, 27.0), ("ashtray_right", 42.0, 30.0, 32.0, 19.0)):
        objs.append(SceneObject("cylinder", pose_at(x, 0, z + dz), Uniform(0.9), radius_mm=r, height_mm=20, name=name))
        objs.append(SceneObject("disc", pose_at(x, 0, z + dz - 10.5), Noise(3, 7, 0.1, 0.25), radius_mm=r_bowl,
                                name=f"{name}_bowl"))
    return Scene(tuple(objs), regulated_light(z), z + 500, Uniform(0.08), "fig5b")


def fig6(seed: int = 6, count: int = 14) -> Scene:
    """A cluttered scene: ``count`` mixed objects at 500-1000 mm with seeded poses and textures."""
    check_object_count(check_count(count, "count"))
    rng = np.random.default_rng(seed)
    objs = []
    kinds = ("box", "cylinder", "sphere", "rectangle", "disc")
    for i in range(count):
        kind = kinds[i % len(kinds)]
        z = rng.uniform(500, 1000)
        x, y = rng.uniform(-0.3, 0.3) * z, rng.uniform(-0.2, 0.2) * z
        rot = rng.uniform(-40, 40, 3)
        tex = (Noise(rng.uniform(3, 12), int(rng.integers(1000)), 0.8, 0.95) if i % 3 else
               Checker(rng.uniform(8, 20), 0.1, 0.95))
        kw = {"box": {"size_mm": tuple(rng.uniform(30, 80, 3))},
              "rectangle": {"size_mm": tuple(rng.uniform(40, 90, 2))},
              "cylinder": {"radius_mm": rng.uniform(12, 30), "height_mm": rng.uniform(30, 80)},
              "sphere": {"radius_mm": rng.uniform(15, 35)}, "disc": {"radius_mm": rng.uniform(15, 35)}}[kind]
        objs.append(SceneObject(kind, pose_at(x, y, z, *rot), tex, name=f"{kind}_{i}", **kw))
    return Scene(tuple(objs), regulated_light(750.0), 1400.0, Noise(40, seed, 0.05, 0.2), "fig6")


def fig9(distance_mm: float = 600.0, tilt_x_deg: float = 0.0, tilt_y_deg: float = 0.0, x_mm: float = 0.0,
         y_mm: float = 0.0) -> Scene:
    """The paper's accuracy pattern: five black circles (10 mm, centres 20 mm apart) on a white sheet
    (120 x 50 mm) at ``distance_mm``, turned by the tilts (deg), on a dark backdrop 400 mm behind."""
    sheet = SceneObject("rectangle", pose_at(x_mm, y_mm, distance_mm, tilt_x_deg, tilt_y_deg, 0),
                        Circles(10.0, 20.0, 5, 0.05, 0.9), size_mm=(120.0, 50.0), name="pattern")
    return Scene((sheet,), regulated_light(distance_mm), distance_mm + 400, Uniform(0.08), "fig9")


def seam_mesh(radius_mm: float = 150.0, length_mm: float = 240.0, width_mm: float = 160.0,
              height_amplitude_mm: float = 20.0, bevel_width_mm: float = 6.0, bevel_depth_mm: float = 3.0,
              gap: tuple[float, float] | None = None, steps: int = 480):
    """Two plates meeting along a curved V-groove seam, as (vertices (V, 3) mm, plate faces, groove faces)
    in a local frame whose x runs along the seam, y across it and z up (toward the camera when posed).

    The seam's centre line is y(x) = R - sqrt(R^2 - x^2) (curvature radius R), its height varies as
    A sin(pi x / L); across the seam the surface drops linearly by ``bevel_depth_mm`` within
    ``bevel_width_mm`` of the centre line (a V-groove). ``gap`` = (x0, x1) fills the groove over that
    stretch (the seam disappears there: a gap in the seam).
    """
    xs = np.linspace(-length_mm / 2, length_mm / 2, steps)
    w = np.concatenate([np.linspace(-width_mm / 2, -bevel_width_mm, 8)[:-1],
                        np.linspace(-bevel_width_mm, bevel_width_mm, 9),
                        np.linspace(bevel_width_mm, width_mm / 2, 8)[1:]])
    X, W = np.meshgrid(xs, w, indexing="ij")
    centre_y = radius_mm - np.sqrt(radius_mm ** 2 - X ** 2)
    height = height_amplitude_mm * np.sin(np.pi * X / length_mm)
    filled = np.zeros_like(X, dtype=bool) if gap is None else (X >= gap[0]) & (X <= gap[1])
    groove = np.where(filled, 0.0, bevel_depth_mm * np.clip(1 - np.abs(W) / bevel_width_mm, 0, None))
    V = np.stack([X, centre_y + W, height - groove], axis=-1).reshape(-1, 3)
    nx, nw = X.shape
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(nw - 1), indexing="ij")
    a = (i * nw + j).ravel()
    b, c, d = a + nw, a + nw + 1, a + 1
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    cell_near_seam = np.abs(W[:-1, :-1] + W[1:, 1:]) / 2 < bevel_width_mm
    cell_in_groove = (cell_near_seam & ~(filled[:-1, :-1] & filled[1:, 1:])).ravel()
    in_groove = np.concatenate([cell_in_groove, cell_in_groove])
    return V, F[~in_groove], F[in_groove]


def seam_centre_line(x_mm: np.ndarray, radius_mm: float = 150.0, length_mm: float = 240.0,
                     height_amplitude_mm: float = 20.0, bevel_depth_mm: float = 3.0) -> np.ndarray:
    """The true seam (groove bottom) in the workpiece's local frame, (N, 3) mm, for local x positions."""
    x = np.asarray(x_mm, dtype=float)
    return np.stack([x, radius_mm - np.sqrt(radius_mm ** 2 - x ** 2),
                     height_amplitude_mm * np.sin(np.pi * x / length_mm) - bevel_depth_mm], axis=-1)


#: The longest seam :func:`weld_seam` builds, mm: its mesh grows with the length (two vertex columns a mm),
#: and no cell's arm follows a longer one.
MAX_SEAM_MM = 2000.0


def weld_seam(distance_mm: float = 450.0, radius_mm: float = 150.0, height_amplitude_mm: float = 20.0,
              gap_start_mm: float | None = None, gap_length_mm: float = 0.0, length_mm: float = 240.0,
              width_mm: float = 160.0) -> Scene:
    """Two plates meeting along a curved beveled seam, facing the camera at ``distance_mm`` (the workpiece's
    local z points toward the camera, so its heights move toward the rig)."""
    gap = None if gap_start_mm is None else (gap_start_mm, gap_start_mm + gap_length_mm)
    if not 0 < length_mm <= 2 * radius_mm:
        raise ValueError(f"weld_seam: length_mm must be in (0, 2 radius_mm], got {length_mm!r}")
    if not length_mm <= MAX_SEAM_MM:
        raise ValueError(f"weld_seam: length_mm must be at most {MAX_SEAM_MM:g} mm (the mesh holds two vertex "
                         f"columns a mm; a PUMA 560 reaches 0.86 m), got {length_mm!r}")
    V, plates, groove = seam_mesh(radius_mm=radius_mm, length_mm=length_mm, width_mm=width_mm,
                                  height_amplitude_mm=height_amplitude_mm, gap=gap,
                                  steps=max(2, int(2 * length_mm)))
    pose = pose_at(0.0, -radius_mm / 4, distance_mm, 180.0, 0.0, 0.0)  # local z toward the camera
    objs = (SceneObject("mesh", pose, Noise(4, 11, 0.45, 0.7), vertices_mm=V, faces=plates, name="plates"),
            SceneObject("mesh", pose, Noise(2, 12, 0.08, 0.18), vertices_mm=V, faces=groove, name="seam groove"))
    return Scene(objs, Lighting(ambient=0.25, lamp=0.75, reference_mm=distance_mm), distance_mm + 300,
                 Uniform(0.05), "weld_seam")


def photo_texture(name: str, size_mm: tuple[float, float]) -> ImageTexture:
    """One of scikit-image's bundled photographs (CC0 or public domain), grey in [0, 1], as a texture."""
    from skimage import data
    from skimage.color import rgb2gray

    img = getattr(data, name)()
    grey = rgb2gray(img) if img.ndim == 3 else img / 255.0
    return ImageTexture(np.asarray(grey, dtype=np.float64), size_mm, f"skimage.data.{name}")


def textured(distance_mm: float = 800.0) -> Scene:
    """Photo-textured panel, box, ball and backdrop at 0.7-1.4 x distance_mm, for dense disparity."""
    z = distance_mm
    objs = (
        SceneObject("rectangle", pose_at(-60, -40, z, 0, 25, 0), photo_texture("astronaut", (260, 180)),
                    size_mm=(260, 180), name="panel"),
        SceneObject("sphere", pose_at(90, 60, 0.78 * z), photo_texture("grass", (90, 90)), radius_mm=45, name="ball"),
        SceneObject("box", pose_at(-110, 90, 0.7 * z, 10, 30, 0), photo_texture("brick", (90, 70)),
                    size_mm=(90, 70, 60), name="crate"),
    )
    return Scene(objs, regulated_light(z), 1.4 * z, photo_texture("gravel", (1.3 * z, 1.0 * z)), "textured")


def wall(distance_mm: float = 700.0, seed: int = 0) -> Scene:
    """A flat wall of fine seeded value noise facing the rig at distance_mm, filling the field (a tare)."""
    if seed < 0:
        raise ValueError(f"wall: seed must be >= 0, got {seed}")
    z = distance_mm
    return Scene((), regulated_light(z), z, Noise(scale_mm=0.002 * z, seed=seed), "wall")


BUILTINS = {"fig5a": fig5a, "fig5b": fig5b, "fig6": fig6, "fig9": fig9, "weld_seam": weld_seam,
            "textured": textured, "wall": wall}


def describe() -> list[tuple[str, str, str]]:
    """(name, one-line description, parameters with defaults) of every built-in scene."""
    out = []
    for name, fn in BUILTINS.items():
        params = ", ".join(f"{p.name}={p.default}" for p in inspect.signature(fn).parameters.values())
        out.append((name, (fn.__doc__ or "").strip().splitlines()[0], params))
    return out


def builtin_scene(spec: str) -> Scene:
    """A built-in scene from ``name`` or ``name:key=value,key=value`` (e.g. ``fig9:distance_mm=800``)."""
    name, kwargs = parse_spec(spec)
    return BUILTINS[name](**kwargs)


def parse_spec(spec: str) -> tuple[str, dict]:
    """(name, keyword arguments) of a built-in scene spec ``name[:key=value,...]``; ValueError naming the
    parameter when a key is unknown, given twice or without its ``=value``, or a value is not a number or out
    of range."""
    name, _, args = spec.partition(":")
    if name not in BUILTINS:
        raise ValueError(f"unknown built-in scene {name!r} (known: {', '.join(BUILTINS)})")
    fn = BUILTINS[name]
    params = inspect.signature(fn).parameters
    kwargs = {}
    for item in filter(None, args.split(",")):
        key, eq, value = (s.strip() for s in item.partition("="))
        if key not in params:
            raise ValueError(f"{name}: unknown parameter {key!r} (known: {', '.join(params)})")
        if not eq:
            raise ValueError(f"{name}: {key} needs a value: {key}=<number>")
        if key in kwargs:
            raise ValueError(f"{name}: {key} is given twice")
        try:
            kwargs[key] = type(params[key].default)(value) if params[key].default is not None else float(value)
        except ValueError:
            raise ValueError(f"{name}: {key} must be a number, got {value!r}") from None
        v = kwargs[key]
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"{name}: {key} must be finite, got {value!r}")
        if key.endswith(("distance_mm", "radius_mm", "length_mm", "width_mm")) and v <= 0:
            raise ValueError(f"{name}: {key} must be > 0 mm, got {value!r}")
    return name, kwargs
