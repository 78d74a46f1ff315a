"""The renderer's rays and shading: the scene rays of every sub-pixel sample of a view (traced once per rig
through the exact optics, :func:`psvs.optics.trace.trace_pixels`, and cached), and the radiance along them
(Lambertian albedo under ambient light and a lamp, with shadows: :func:`shade`). psvs.simulate.render and
psvs.simulate.adaptive build images from them."""
from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from psvs._threads import pool_size
from psvs.optics.rig import Rig
from psvs.optics.trace import camera_dirs, trace_camera_rays, trace_pixels
from psvs.simulate.geometry import Hits, SceneGeometry, group_by
from psvs.simulate.kernels import lamp_rays, lit_radiance
from psvs.simulate.scene import Scene

#: mm: a shadow ray starts this far off its surface, beyond the tessellated shell of curved surfaces.
SHADOW_OFFSET_MM = 0.1


def view_rays(rig: Rig, supersample: int, view: str):
    """Scene rays of every sub-pixel sample of one view: (origins (H*W*K*K, 3), dirs, valid), cached per rig
    (both views' at once: :func:`_both_views`)."""
    if view not in ("left", "right"):
        raise ValueError(f"view must be 'left' or 'right', got {view!r}")
    return _both_views(rig, int(supersample))[view]


@functools.lru_cache(maxsize=4)
def _both_views(rig: Rig, supersample: int) -> dict:
    """Both views' :func:`view_rays`, read-only: the camera's rays of the samples are found once (undoing the
    lens's distortion, an iteration a sample) and traced through each view's path."""
    w, h = rig.camera.image_size_px
    dirs = camera_dirs(_sample_pixels(rig, supersample, np.arange(h * w)), rig.camera)
    out = {}
    for view in ("left", "right"):
        rays = trace_camera_rays(dirs, rig, view)
        for a in rays:
            a.setflags(write=False)
        out[view] = rays
    return out


def _sample_pixels(rig: Rig, supersample: int, pixels: np.ndarray) -> np.ndarray:
    """The K x K sub-pixel sample positions (N*K*K, 2) px of the pixels ``pixels`` (flat indices v * W + u,
    (N,)), each pixel's samples together, row by row of its K x K grid."""
    w = rig.camera.image_size_px[0]
    offs = (np.arange(supersample) + 0.5) / supersample - 0.5
    v, u = np.divmod(np.asarray(pixels, dtype=np.int64), w)
    dv, du = (a.ravel() for a in np.meshgrid(offs, offs, indexing="ij"))
    return np.column_stack([(u[:, None] + du[None, :]).ravel(), (v[:, None] + dv[None, :]).ravel()])


def sample_rays(rig: Rig, supersample: int, view: str, pixels: np.ndarray):
    """Scene rays of the K x K sub-pixel samples (K = ``supersample``) of the pixels ``pixels`` (flat indices
    v * W + u, (N,)) of one view: (origins (N*K*K, 3), dirs, valid), each pixel's samples together, row by
    row of its K x K grid (as :func:`view_rays` orders them), traced now (no cache)."""
    return trace_pixels(_sample_pixels(rig, supersample, pixels), rig, view)


def shade(geom: SceneGeometry, scene: Scene, hits: Hits) -> np.ndarray:
    """Radiance (N,) of each hit: albedo * (ambient + lamp * max(0, n.l) (ref / r)^2 * unshadowed); 0 on a miss.
    The lamp's terms and the shadow rays are one pass each (:mod:`psvs.simulate.kernels`)."""
    light = scene.lighting
    hit = hits.obj >= 0
    albedo = np.zeros(len(hits.t_mm))
    for k, sel in group_by(hits.obj):
        if k >= 0:
            albedo[sel] = geom.objects[k].texture(geom.local_xy(k, hits.points_mm[sel]))
    if light.lamp > 0 and hit.any():
        r2, cos, lit, start, ldir, length = lamp_rays(hits.points_mm, hits.normals, hit,
                                                      np.asarray(light.lamp_position_mm, dtype=np.float64),
                                                      SHADOW_OFFSET_MM)
        # a shadow ray starts beyond the tessellated shell that circumscribes curved surfaces (< 0.01 mm thick)
        shadowed = geom.occluded(start, ldir, length) if light.shadows and len(lit) else np.zeros(len(lit), bool)
        lit_radiance(albedo, hit, r2, cos, lit, shadowed, float(light.ambient),
                     float(light.lamp * light.reference_mm ** 2))
    else:
        albedo *= light.ambient
        albedo[~hit] = 0.0
    return albedo


CHUNK_RAYS = 1 << 16  # measured best on 2 cores (docs/benchmarks.md)


def radiance(geom: SceneGeometry, scene: Scene, rays) -> np.ndarray:
    """Radiance (N,) along traced rays; vignetted rays bring no light. Cache-sized chunks, one per
    thread (NumPy and Embree release the GIL)."""
    n = len(rays.valid)
    out = np.zeros(n)

    def one(a):
        b = min(a + CHUNK_RAYS, n)
        valid = rays.valid[a:b]
        if valid.all():
            out[a:b] = shade(geom, scene, geom.intersect(rays.origins_mm[a:b], rays.dirs[a:b], refine=False))
        elif valid.any():
            ok = np.flatnonzero(valid) + a
            out[ok] = shade(geom, scene, geom.intersect(rays.origins_mm[ok], rays.dirs[ok], refine=False))

    with ThreadPoolExecutor(pool_size()) as ex:
        list(ex.map(one, range(0, n, CHUNK_RAYS)))
    return out
