"""The scenes of the dense sweep, sized for a drawn rig (:mod:`tests.support.rig_draws`), rendered through
its build, written and read back as the user's files, with the depth the left view sees; and the score of a
dense result against it.

Scenes (:data:`SCENES`; the textured ones are photo collages, the blank and the noise have no echo):

- ``cards``: two or three photo cards at 15-60 % of the working range, turned a little, before a photo wall
  at 90 % of it;
- ``slanted``: a photo panel turned 30-40 deg about the vertical across the middle of the range, before a
  photo wall at its far end;
- ``far_wall``: a photo wall at the far end of the range, filling both views;
- ``blank``: a plain wall (uniform albedo) in the middle of the range, filling both views;
- ``noise``: a frame with nothing to see (the lens capped, the gain turned up): sensor noise only.

A photo collage (:func:`collage`) tiles random crops of scikit-image's photographs (each crop a new one,
flipped or turned at random and scaled by 0.8-1.25) at about one texel per 1.5 pixels of the nearest depth
the surface is seen at, so its texture reaches the pixel scale at every camera resolution without
repeating itself (a tiled photo would repeat at its own period, which a disparity can equal).
"""
from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass

import numpy as np

from psvs.dense.build import dense_on_rig, rig_cloud
from psvs.dense.params import DEFAULT, FAST
from psvs.simulate.builtin import pose_at, regulated_light
from psvs.simulate.scene import Scene, SceneObject
from psvs.simulate.textures import ImageTexture, Uniform
from tests.support.adaptive import render_irradiance
from tests.support.rig_draws import (
    ALL_MP,
    CALIBRATION_MM,
    RigDraw,
    calibrated_draw,
    camera_frame,
    draw_rig,
    read_frame,
    save_frame,
    scratch,
)

#: Scenes the dense answer must be right on (textured) and those it must refuse (no echo).
TEXTURED = ("cards", "slanted", "far_wall")
UNTEXTURED = ("blank", "noise")
SCENES = TEXTURED + UNTEXTURED
#: skimage.data photographs the collages are cut from: those with texture over their whole frame (not the
#: coins' or the rocket's plain background, nor the brick wall, which repeats); stereo_motorcycle's left view.
PHOTOS = ("gravel", "grass", "astronaut", "coffee", "chelsea", "immunohistochemistry", "stereo_motorcycle")


@functools.lru_cache(maxsize=None)
def _photo_grey(name: str) -> np.ndarray:
    from skimage import data
    from skimage.color import rgb2gray
    img = getattr(data, name)()
    img = img[0] if isinstance(img, tuple) else img
    grey = rgb2gray(img) if img.ndim == 3 else img / 255.0
    return np.asarray(grey, dtype=np.float64)


def collage(size_mm: tuple[float, float], texel_mm: float, seed: int) -> ImageTexture:
    """A photo collage (module docstring) of ``size_mm`` (width, height) at ``texel_mm`` per texel."""
    import cv2
    rng = np.random.default_rng(seed)
    w, h = (max(8, int(math.ceil(s / texel_mm))) for s in size_mm)
    out = np.empty((h, w))
    tile = int(rng.integers(160, 260))
    for y in range(0, h, tile):
        for x in range(0, w, tile):
            photo = _photo_grey(PHOTOS[rng.integers(len(PHOTOS))])
            side = int(tile / rng.uniform(0.8, 1.25))
            side = min(side, *photo.shape)
            y0, x0 = rng.integers(0, photo.shape[0] - side + 1), rng.integers(0, photo.shape[1] - side + 1)
            crop = photo[y0:y0 + side, x0:x0 + side]
            crop = np.rot90(crop, int(rng.integers(4)))
            if rng.random() < 0.5:
                crop = crop[:, ::-1]
            crop = cv2.resize(np.ascontiguousarray(crop), (tile, tile), interpolation=cv2.INTER_AREA if side > tile
                              else cv2.INTER_LINEAR)
            lo, hi = np.percentile(crop, (2, 98))
            gain = rng.uniform(0.6, 0.9) / max(hi - lo, 0.05)
            crop = np.clip(0.5 + (crop - 0.5 * (lo + hi)) * gain, 0.02, 0.98)
            out[y:y + tile, x:x + tile] = crop[:min(tile, h - y), :min(tile, w - x)]
    return ImageTexture(out, (float(size_mm[0]), float(size_mm[1])), f"collage(seed={seed})")


def footprint_mm(draw: RigDraw, z_mm: float) -> float:
    """The size of one pixel at depth ``z_mm`` (mm), through the nominal lens."""
    cam = draw.nominal.camera
    return (z_mm - draw.nominal.virtual_z_mm) * cam.pixel_pitch_mm[0] / cam.focal_length_mm


def field_mm(draw: RigDraw, z_mm: float, margin: float = 1.25) -> tuple[float, float]:
    """(width, height) mm a wall at ``z_mm`` must have to fill both views, with ``margin`` (the lens's
    barrel widens the field)."""
    cam, b = draw.nominal.camera, draw.nominal.mirrors.baseline_mm
    a_x, a_y = cam.half_fov_rad
    z = z_mm - draw.nominal.virtual_z_mm
    return margin * (2 * z * math.tan(a_x) + b), margin * 2 * z * math.tan(a_y)


def _wall(draw: RigDraw, z_mm: float, seed: int) -> tuple[float, ImageTexture]:
    size = field_mm(draw, z_mm)
    return z_mm, collage(size, 1.5 * footprint_mm(draw, z_mm), seed)


def make_scene(draw: RigDraw, name: str) -> Scene | None:
    """The scene ``name`` of :data:`SCENES` for the draw (None for ``noise``: no scene at all)."""
    rng = np.random.default_rng([draw.seed, SCENES.index(name)])
    near, far = draw.near_mm, draw.far_mm
    span = far - near
    if name == "cards":
        z_wall, wall = _wall(draw, near + 0.9 * span, draw.seed * 10 + 1)
        objs = []
        for k in range(2 + int(rng.integers(2))):
            z = near + rng.uniform(0.15, 0.6) * span
            fw, fh = field_mm(draw, z, margin=1.0)
            size = (rng.uniform(0.2, 0.3) * fw, rng.uniform(0.25, 0.4) * fh)
            x, y = rng.uniform(-0.3, 0.3) * fw, rng.uniform(-0.25, 0.25) * fh
            tex = collage(size, 1.5 * footprint_mm(draw, z), draw.seed * 10 + 2 + k)
            objs.append(SceneObject("rectangle", pose_at(x, y, z, rng.uniform(-8, 8), rng.uniform(-20, 20),
                                                     rng.uniform(-5, 5)), tex, size_mm=size, name=f"card{k}"))
        return Scene(tuple(objs), regulated_light(near + 0.5 * span), z_wall, wall, "cards")
    if name == "slanted":
        z = near + 0.5 * span
        fw, fh = field_mm(draw, z, margin=1.0)
        size = (0.45 * fw, 0.5 * fh)
        turn = rng.uniform(30, 40) * rng.choice([-1, 1])
        # its nearest part (half its width times sin(turn) nearer than its centre) sets the texel size
        near_edge = z - 0.5 * size[0] * math.sin(math.radians(abs(turn)))
        tex = collage(size, 1.5 * footprint_mm(draw, near_edge), draw.seed * 10 + 5)
        z_wall, wall = _wall(draw, far, draw.seed * 10 + 6)
        panel = SceneObject("rectangle", pose_at(rng.uniform(-0.1, 0.1) * fw, 0.0, z, rng.uniform(-5, 5), turn, 0.0),
                            tex, size_mm=size, name="panel")
        return Scene((panel,), regulated_light(z), z_wall, wall, "slanted")
    if name == "far_wall":
        z_wall, wall = _wall(draw, far, draw.seed * 10 + 7)
        return Scene((), regulated_light(far), z_wall, wall, "far_wall")
    if name == "blank":
        return Scene((), regulated_light(near + 0.5 * span), near + 0.5 * span, Uniform(0.6), "blank")
    if name == "noise":
        return None
    raise ValueError(f"unknown scene {name!r} (known: {', '.join(SCENES)})")


def left_truth(scene: Scene, rig, geom=None) -> np.ndarray:
    """Z (H, W) mm of the point each left-view pixel centre sees, NaN where the right view does not see that
    point (outside its field or hidden): the left half of ``psvs.simulate.render.ground_truth`` (its
    ``depth_left_mm`` where ``valid_left``), which the score needs and which costs half as much."""
    from psvs.optics.project import in_image, project_points
    from psvs.optics.trace import trace_pixels
    from psvs.simulate.geometry import SceneGeometry
    from psvs.simulate.radiance import view_rays
    from psvs.simulate.render import VISIBILITY_TOL_MM
    geom = geom or SceneGeometry(scene)
    w, h = rig.camera.image_size_px
    rays = view_rays(rig, 1, "left")
    hits = geom.intersect(rays.origins_mm, rays.dirs)
    seen = np.flatnonzero(rays.valid & (hits.obj >= 0))
    pts = hits.points_mm[seen]
    uv, ok = project_points(pts, rig, "right")
    ok &= in_image(uv, rig)
    back = trace_pixels(uv[ok], rig, "right")
    h2 = geom.intersect(back.origins_mm, back.dirs)
    vis = back.valid & (np.linalg.norm(h2.points_mm - pts[ok], axis=1) < VISIBILITY_TOL_MM)
    ok[np.flatnonzero(ok)[~vis]] = False
    z = np.full(w * h, np.nan)
    z[seen[ok]] = pts[ok, 2]
    return z.reshape(h, w)


#: The noise frame: the lens capped (1 % of full well from stray light) at 16 times the gain.
NOISE_IRRADIANCE, NOISE_GAIN = 0.01, 16.0


@dataclass(frozen=True, eq=False)
class Shot:
    """One scene through a draw: the frame file, the frame as psvs reads it (H, W) uint8, the left view's
    depth truth (H, W) mm (NaN where the right view does not see the point; None for an untextured scene),
    the share of the renderer's samples traced (:func:`tests.support.adaptive.render_irradiance`), the
    seconds of the render and of the truth."""

    scene: str
    path: object
    image: np.ndarray
    truth_mm: np.ndarray | None
    supersampled: float
    seconds: dict


@functools.lru_cache(maxsize=None)
def shot(seed: int, scene: str, megapixels: tuple[float, float] = ALL_MP) -> Shot:
    """Scene ``scene`` of the draw of ``seed`` through its build (the renderer's 2 x 2 samples a pixel, where
    the image is not smooth for the plain wall: :mod:`tests.support.adaptive`), the frame its camera gives
    saved as its file and read back as psvs reads it; the truth for a textured scene (:func:`left_truth`);
    cached per test session."""
    from psvs.simulate.geometry import SceneGeometry
    from psvs.simulate.sensor import Sensor
    draw = draw_rig(seed, megapixels)
    sc = make_scene(draw, scene)
    t0 = time.perf_counter()
    sensor, truth, share = Sensor(), None, 0.0
    if sc is None:
        w, h = draw.size_px
        irradiance = np.full((h, w), NOISE_IRRADIANCE)
        sensor = Sensor(gain=NOISE_GAIN)
    else:
        irradiance, share = render_irradiance(sc, draw.build, adaptive=scene == "blank")
    t1 = time.perf_counter()
    if scene in TEXTURED:
        truth = left_truth(sc, draw.build, SceneGeometry(sc))
    t2 = time.perf_counter()
    frame = camera_frame(irradiance, draw, seed=7919 * seed + 31 * draw.candidate + SCENES.index(scene), sensor=sensor)
    folder = scratch(f"scenes-{seed}-{draw.megapixels[0]:g}-{draw.megapixels[1]:g}")
    path = save_frame(folder / scene, frame, draw)
    return Shot(scene, path, read_frame(path, draw), truth, share, {"render": t1 - t0, "truth": t2 - t1})


@dataclass(frozen=True, eq=False)
class Score:
    """A dense result scored: ``bad``: the share of twin-visible pixels with no answer or |Z error| > 2 % of
    Z; ``pixels``: how many twin-visible pixels; the gate's ``count`` (trusted pixels of the left map),
    ``strongest_z`` (the strongest echo's z, in spreads of its correlations) and ``chance`` (its family's
    1 % false-alarm level, psvs.dense.echo_test); seconds of the maps and of the gate."""

    bad: float
    pixels: int
    count: int
    strongest_z: float
    chance: float
    seconds: dict

    @property
    def answered(self) -> bool:
        return self.count > 0


def score_text(s: Score) -> str:
    """One line: the bad share, the twin-visible pixels, the gate's figures."""
    verdict = f"answered ({s.count} px trusted)" if s.answered else "refused"
    return (f"{s.bad:.1%} of {s.pixels} twin-visible px wrong, {verdict}: the strongest echo {s.strongest_z:.1f} "
            f"spreads, chance up to {s.chance:.1f}")


def score(image: np.ndarray, truth_mm, rig, near_mm: float, far_mm: float, params) -> Score:
    """Dense depth of ``image`` through ``rig`` (``dense_on_rig``, ``rig_cloud``) and the gate
    (``rig_trust``), against ``truth_mm`` (None: only the gate)."""
    from psvs.dense.build import rig_trust
    t0 = time.perf_counter()
    dense = dense_on_rig(image, rig, near_mm, far_mm, params=params)
    t1 = time.perf_counter()
    trust = rig_trust(dense)
    t2 = time.perf_counter()
    bad, n = float("nan"), 0
    if truth_mm is not None:
        cloud = rig_cloud(dense, rig)
        truth = truth_mm if dense.rect is None else truth_on_left_grid(truth_mm, dense.rect, cloud.depth_mm.shape)
        valid = np.isfinite(truth)
        err = np.abs(cloud.depth_mm[valid] - truth[valid]) / truth[valid]
        n = int(valid.sum())
        bad = float(np.mean(~(err <= 0.02)))        # NaN (no answer) counts as wrong
    return Score(bad, n, int(trust.trusted_left.sum()), float(trust.test.strongest_z),
                 float(trust.test.strongest_threshold),
                 {"dense": t1 - t0, "trust": t2 - t1})


@functools.lru_cache(maxsize=None)
def scored(seed: int, scene: str, fast: bool, megapixels: tuple[float, float] = ALL_MP) -> Score:
    """:func:`score` of a draw's scene through its *calibrated* rig (never its truth), DEFAULT or FAST params,
    over its working range; cached per test session."""
    cal = calibrated_draw(seed, megapixels)
    s = shot(seed, scene, megapixels)
    return score(s.image, s.truth_mm, cal.rig, cal.draw.near_mm, cal.draw.far_mm, FAST if fast else DEFAULT)


#: Sensor sizes (MP) of the draws.
SMALL, MID, LARGE = (0.3, 0.5), (1.0, 2.5), (2.5, 5.1)
#: The largest share of wrong pixels on a textured scene, by mode.
MAX_BAD = {"default": 0.10, "fast": 0.15}


MODES = tuple(MAX_BAD)


def draw_id(draw) -> str:
    seed, mp = draw
    return f"seed{seed}-{mp[0]:g}-{mp[1]:g}MP"


def check_calibration(seed, megapixels):
    cal = calibrated_draw(seed, megapixels)
    assert cal.ok, f"calibration misses {CALIBRATION_MM} mm:\n{cal.describe()}"


def check_scene(seed, megapixels, scene, mode):
    cal = calibrated_draw(seed, megapixels)
    s = scored(seed, scene, mode == "fast", megapixels)
    what = f"{scene}, {mode}: {score_text(s)}\n{cal.describe()}"
    if scene in TEXTURED:
        assert s.answered, f"a textured scene refused: {what}"
        assert s.bad <= MAX_BAD[mode], f"more than {MAX_BAD[mode]:.0%} wrong: {what}"
    else:
        assert not s.answered, f"a scene without echo answered: {what}"


def truth_on_left_grid(truth, rect, shape):
    """A complex-image map ``truth`` (H, W) on the left view's rectified grid ``shape`` (H', W'): each grid
    pixel takes the complex pixel it maps to (NaN where it maps to none)."""
    h, w = shape
    uu, vv = np.meshgrid(np.arange(w), np.arange(h))
    c = rect.lookup(np.column_stack([uu.ravel(), vv.ravel()]).astype(float), "left")
    z = np.full(h * w, np.nan)
    ok = np.all(np.isfinite(c), axis=1)
    ci = np.rint(c[ok]).astype(int)
    z[ok] = truth[ci[:, 1], ci[:, 0]]
    return z.reshape(h, w)
