"""Render the complex image: both views' chief rays through the exact optics, into the scene, summed.

For every pixel and every one of K x K sub-pixel samples, the left and right chief rays are traced
through the rig (:func:`psvs.optics.trace.trace_pixels`: the M1 plate's refraction, mirror extents and
vignetting), intersected with the scene (:class:`~psvs.simulate.geometry.SceneGeometry`) and shaded
(ambient + the rig's lamp, Lambertian, with shadows). The complex image on the sensor is
C = RI (1 - s) L + RI s R with s the rig's split ratio (the share reflected at M1, the right view) and RI the
lens's relative illumination at the pixel (:mod:`psvs.optics.illumination`; 1 for a flat field).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs import _budget
from psvs.optics.illumination import illumination_map
from psvs.optics.mirrors import mirror_planes
from psvs.optics.project import in_image, project_points
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels
from psvs.simulate.adaptive import adaptive_views
from psvs.simulate.geometry import MovedGeometry, SceneGeometry
from psvs.simulate.radiance import radiance, view_rays
from psvs.simulate.scene import Scene
from psvs.simulate.sensor import Sensor, expose

VISIBILITY_TOL_MM = 1e-3


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """Per-pixel truth at pixel centres, each (H, W). Depth is Z in frame C (mm), NaN where the view sees
    nothing. Disparity u_l - u_r (px) of the point each pixel sees, NaN where that point is outside the
    other view, hidden in it, or absent. ``valid_*`` marks finite disparities."""

    depth_left_mm: np.ndarray
    depth_right_mm: np.ndarray
    disparity_left_px: np.ndarray
    disparity_right_px: np.ndarray
    valid_left: np.ndarray
    valid_right: np.ndarray


@dataclass(frozen=True, eq=False)
class RenderResult:
    """image (H, W) uint8 through the sensor; irradiance (H, W) the noiseless complex image on the sensor
    (1.0 = full well; the lens's relative illumination included); left, right (H, W) each view's radiance
    alone (before the split and the lens's fall-off); truth or None."""

    image: np.ndarray
    irradiance: np.ndarray
    left: np.ndarray
    right: np.ndarray
    truth: GroundTruth | None = None


def rig_front_z_mm(rig: Rig) -> float:
    """The largest z reached by the rig's mirrors (anchors, and rectangle corners when finite), mm."""
    zs = []
    for p in mirror_planes(rig).values():
        zs.append(p.point[2])
        if p.extent is not None:
            for s in p.extent.along_mm:
                zs.append(p.point[2] + s * p.s_axis[2])
    return float(max(zs))


def check_scene_in_front(geom: SceneGeometry, rig: Rig) -> None:
    """Raise ValueError naming the first object that reaches behind the rig's front."""
    front = rig_front_z_mm(rig)
    for k, o in enumerate(geom.objects):
        z = geom.min_z_mm(k)
        if z <= front:
            raise ValueError(f"object {o.name or o.kind!r} is behind the rig: it reaches z = {z:.1f} mm, "
                             f"the mirrors end at z = {front:.1f} mm")


#: Peak bytes per sub-pixel sample of one view while rendering (rays of both views are cached; measured
#: 1.3 GiB at 640x480, K = 4, rounded up).
SAMPLE_BYTES = 300


def render_memory_bytes(rig: Rig, supersample: int) -> int:
    """Estimated peak memory (bytes) of :func:`render_views` for K = ``supersample``: H*W*K*K samples."""
    w, h = rig.camera.image_size_px
    return int(w) * int(h) * int(supersample) ** 2 * SAMPLE_BYTES


def check_supersample(rig: Rig, supersample, name: str = "supersample") -> int:
    """``supersample`` as an int >= 1 whose rendering fits in memory, else ValueError naming ``name``."""
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or supersample < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {supersample!r}")
    k = int(supersample)
    w, h = rig.camera.image_size_px
    fits = max(1, int(math.sqrt(_budget.USABLE_SHARE * _budget.available_bytes() / render_memory_bytes(rig, 1))))
    _budget.check_memory(render_memory_bytes(rig, k), f"{name} {k} ({w}x{h} px x {k * k} samples per pixel)",
                 f"at most {name} {fits} fits")
    return k


#: Seconds one sub-pixel sample costs (both views' rays traced, intersected and shaded): measured 0.3-0.5 us
#: once a rig's rays are cached and 0.7-1.5 us for a rig's first frame, at 640x480 px on the reference host
#: (AMD EPYC, 2 cores). A ground truth costs about two samples a pixel.
SAMPLE_SECONDS = 1e-6


def render_seconds(rig: Rig, supersample: int, frames: int = 1, truth: bool = False) -> float:
    """Estimated time (s) of ``frames`` renders through ``rig`` at K = ``supersample`` (:data:`SAMPLE_SECONDS`)."""
    w, h = rig.camera.image_size_px
    return float(frames) * w * h * (supersample ** 2 + 2 * bool(truth)) * SAMPLE_SECONDS


def check_render_work(rig: Rig, supersample: int, frames: int, what: str, hint: str = "", truth: bool = False) -> None:
    """ValueError before any rendering when one render of ``rig`` at K = ``supersample`` does not fit in
    memory, or when ``frames`` of them would take longer than :data:`psvs._budget.WORK_LIMIT_S`. ``what`` names
    what the user asked for (e.g. ``--views 60``); the message gives the estimate and the limit, then ``hint``."""
    w, h = rig.camera.image_size_px
    k2 = supersample ** 2
    _budget.check_memory(render_memory_bytes(rig, supersample), f"{what}: one render of {w}x{h} px x {k2} "
                         f"sample(s) per pixel", hint)
    samples = float(frames) * w * h * (k2 + 2 * bool(truth))
    _budget.check_time(render_seconds(rig, supersample, frames, truth),
                     f"{what} ({frames} render(s) of {w}x{h} px x {k2} sample(s) per pixel"
                     f"{' with ground truth' if truth else ''}: {samples:.3g} samples at {SAMPLE_SECONDS * 1e6:g} "
                     f"us each)", hint)


def render_views(scene: Scene, rig: Rig, supersample: int = 2, geom: SceneGeometry | None = None,
                 adaptive: bool = False):
    """Each view's radiance image (H, W), averaged over K x K samples per pixel (with ``adaptive``, only where
    the image is not smooth: :func:`psvs.simulate.adaptive.adaptive_views`)."""
    supersample = check_supersample(rig, supersample)
    geom = geom or SceneGeometry(scene)
    check_scene_in_front(geom, rig)
    if adaptive:
        return adaptive_views(geom, scene, rig, supersample)[:2]
    w, h = rig.camera.image_size_px
    out = []
    for view in ("left", "right"):
        rad = radiance(geom, scene, view_rays(rig, int(supersample), view))
        out.append(rad.reshape(h, w, supersample * supersample).mean(axis=2))
    return out[0], out[1]


def complex_irradiance(left: np.ndarray, right: np.ndarray, rig: Rig) -> np.ndarray:
    """The complex image on the sensor (H, W), 1.0 = full well, from each view's radiance (H, W): the M1 plate
    passes 1 - s of the left view's light and reflects s of the right's (s = the rig's split), and the lens's
    relative illumination dims both."""
    s = rig.mirrors.split_ratio
    irradiance = (1.0 - s) * left + s * right
    if rig.camera.vignetted:
        irradiance *= illumination_map(rig.camera)
    return irradiance


def ground_truth(scene: Scene, rig: Rig, geom: SceneGeometry | None = None) -> GroundTruth:
    """Depth and disparity at pixel centres of both views (see :class:`GroundTruth`)."""
    geom = geom or SceneGeometry(scene)
    w, h = rig.camera.image_size_px
    res = {}
    for view, other in (("left", "right"), ("right", "left")):
        rays = view_rays(rig, 1, view)
        hits = geom.intersect(rays.origins_mm, rays.dirs)
        seen = rays.valid & (hits.obj >= 0)
        depth = np.where(seen, hits.points_mm[:, 2], np.nan)
        uv_other, ok = project_points(hits.points_mm[seen], rig, other)
        ok &= in_image(uv_other, rig)
        # the point must be what the other view actually sees at that exact position (not hidden)
        back = trace_pixels(uv_other[ok], rig, other)
        h2 = geom.intersect(back.origins_mm, back.dirs)
        vis = back.valid & (np.linalg.norm(h2.points_mm - hits.points_mm[seen][ok], axis=1) < VISIBILITY_TOL_MM)
        ok[np.flatnonzero(ok)[~vis]] = False
        disp = np.full(w * h, np.nan)
        u_pix = np.tile(np.arange(w, dtype=float), h)
        seen_idx = np.flatnonzero(seen)
        if view == "left":
            disp[seen_idx[ok]] = u_pix[seen_idx[ok]] - uv_other[ok, 0]
        else:
            disp[seen_idx[ok]] = uv_other[ok, 0] - u_pix[seen_idx[ok]]
        res[view] = (depth.reshape(h, w), disp.reshape(h, w))
    return GroundTruth(res["left"][0], res["right"][0], res["left"][1], res["right"][1],
                       np.isfinite(res["left"][1]), np.isfinite(res["right"][1]))


def render(scene: Scene, rig: Rig, *, supersample: int = 2, sensor: Sensor = Sensor(), seed: int | None = 0,
           truth: bool = False, adaptive: bool = False,
           geometry: SceneGeometry | MovedGeometry | None = None) -> RenderResult:
    """Render the complex image of a scene through a rig.

    Parameters
    ----------
    scene : Scene
    rig : Rig
    supersample : int
        K: K x K samples per pixel (anti-aliasing).
    sensor : Sensor
        Blur, noise, gain; :data:`psvs.simulate.sensor.IDEAL` for quantisation only.
    seed : int or None
        Noise seed (same seed, same image).
    truth : bool
        Also compute the per-pixel :class:`GroundTruth`.
    adaptive : bool
        Spend the K x K samples only where the image is not smooth (:mod:`psvs.simulate.adaptive`: the same
        image within 1e-6 of full well, 3-5 times faster on a card or the accuracy pattern), for scenes whose
        features are 3 px wide or more.
    geometry : SceneGeometry or MovedGeometry, optional
        ``scene``'s ray-tracing geometry, built beforehand: a camera moving through one rigid scene moves the
        scene's geometry built once (:func:`psvs.simulate.sequence.render_from`) instead of building it for
        every frame.

    Returns
    -------
    RenderResult
    """
    geom = SceneGeometry(scene) if geometry is None else geometry
    left, right = render_views(scene, rig, supersample, geom, adaptive)
    irradiance = complex_irradiance(left, right, rig)
    image = expose(irradiance, sensor, seed)
    return RenderResult(image, irradiance, left, right, ground_truth(scene, rig, geom) if truth else None)
