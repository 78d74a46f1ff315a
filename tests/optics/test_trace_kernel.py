"""The compiled tracer (psvs.optics.trace.trace_camera_rays, one pass a ray) against the NumPy form it replaces on
every pixel and projection (trace_rays surface by surface, then psvs.optics.solids.occluded on the recorded path),
on drawn rigs: mirror extents from tight (other mirrors block part of the field) to unbounded, tilts and shifts,
a turned box, plates 0-3 mm and indices 1.45-1.95, rays over and beyond the field (behind the camera included)
and NaN rows."""
import dataclasses

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.optics.mirrors import path
from psvs.optics.rig import MirrorError, MirrorExtent
from psvs.optics.solids import finite_solids, occluded
from psvs.optics.trace import camera_dirs, ideal_sensor_from_pixels, trace_camera_rays, trace_pixels, trace_rays
from tests.support.geometry import EXAMPLES


def _numpy_trace(dirs, rig, view, occlusion=True):
    hits: list = []
    rays = trace_rays(np.zeros_like(dirs), dirs, path(rig, view), hits)
    if occlusion and finite_solids(rig):
        rays = rays._replace(valid=rays.valid & ~occluded(rig, hits, rays.origins_mm, rays.dirs))
    return rays


def _drawn_rig(seed: int):
    rng = np.random.default_rng(seed)
    rig = default_rig().replace(plate_thickness_mm=float(rng.choice([0.0, rng.uniform(0.5, 3.0)])),
                                refractive_index=float(rng.uniform(1.45, 1.95)),
                                box_rotation_rad=tuple(np.radians(rng.uniform(-0.5, 0.5, 3))))
    extents = {}
    for name in ("m1", "m2", "m3", "m4"):
        if rng.random() < 0.8:    # some unbounded (the paper's ideal plane), most finite, some tight
            s0, s1 = -rng.uniform(5, 45), rng.uniform(5, 45)
            h = rng.uniform(5, 30)
            extents[name] = MirrorExtent((s0, s1), (-h, h * rng.uniform(0.5, 1.5)))
        else:
            extents[name] = None
    errors = {k: MirrorError(tuple(np.radians(rng.uniform(-1, 1, 2))), float(rng.uniform(-1, 1)))
              for k in ("m1", "m2", "m3", "m4")}
    return rig.with_extents(extents).with_errors(errors)


def _drawn_dirs(rig, seed: int, n: int = 20000):
    rng = np.random.default_rng(seed + 100)
    w, h = rig.camera.image_size_px
    uv = np.column_stack([rng.uniform(-0.3 * w, 1.3 * w, n), rng.uniform(-0.3 * h, 1.3 * h, n)])
    d = camera_dirs(uv, rig.camera).copy()
    d[:50] = rng.normal(size=(50, 3))              # any direction, behind the camera included
    d[:50] /= np.linalg.norm(d[:50], axis=1, keepdims=True)
    d[50:55] = np.nan
    d[55, 2] = np.nan
    return d


def _assert_same(got, want, what):
    np.testing.assert_array_equal(got.valid, want.valid, err_msg=what)
    v = want.valid
    np.testing.assert_allclose(got.origins_mm[v], want.origins_mm[v], rtol=0, atol=1e-9, err_msg=what)
    np.testing.assert_allclose(got.dirs[v], want.dirs[v], rtol=0, atol=1e-12, err_msg=what)


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("view", ["left", "right"])
def test_the_compiled_tracer_is_the_numpy_form(seed, view):
    rig = _drawn_rig(seed)
    dirs = _drawn_dirs(rig, seed)
    for occlusion in (True, False):
        want = _numpy_trace(dirs, rig, view, occlusion)
        _assert_same(trace_camera_rays(dirs, rig, view, occlusion), want, f"seed {seed}, {view}, {occlusion}")


def test_the_draws_block_and_vignette():
    """The drawn rigs exercise every branch: rays vignetted, rays blocked by another solid, rays clear."""
    blocked = vignetted = clear = 0
    for seed in range(12):
        rig = _drawn_rig(seed)
        dirs = _drawn_dirs(rig, seed)
        for view in ("left", "right"):
            plain = _numpy_trace(dirs, rig, view, occlusion=False).valid
            full = trace_camera_rays(dirs, rig, view).valid
            blocked += int((plain & ~full).sum())
            vignetted += int((~plain).sum())
            clear += int(full.sum())
    assert blocked > 1000 and vignetted > 10000 and clear > 100000, (blocked, vignetted, clear)


@pytest.mark.parametrize("name", ["clear", "mv1440_misaligned"])
def test_shipped_rigs_over_their_whole_field(name):
    """Every 7th pixel of a shipped rig's frame, both views, through trace_pixels (the compiled tracer) and the
    NumPy form (trace_pixels with a record of the path's hits)."""
    rig = load_rig(EXAMPLES / "rigs" / f"{name}.toml")
    w, h = rig.camera.image_size_px
    v, u = np.mgrid[0:h:7, 0:w:7]
    uv = np.column_stack([u.ravel(), v.ravel()]).astype(float)
    for view in ("left", "right"):
        _assert_same(trace_pixels(uv, rig, view), trace_pixels(uv, rig, view, hits=[]), f"{name} {view}")


def test_many_rays_on_several_threads_equal_one():
    from psvs._threads import thread_share
    rig = load_rig(EXAMPLES / "rigs" / "mv1440_misaligned.toml")
    dirs = _drawn_dirs(rig, 7, n=300_000)
    with thread_share(1):
        one = trace_camera_rays(dirs, rig, "left")
    with thread_share(4):
        many = trace_camera_rays(dirs, rig, "left")
    for a, b in zip(one, many, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", range(4))
def test_camera_dirs_are_the_sensor_points_undistorted_and_normalised(seed):
    """camera_dirs (one compiled pass a pixel) against its formula in NumPy: the sensor point, the lens's
    distortion undone (ideal_sensor_from_pixels), (x, y, f) over its length; a lens without distortion too."""
    rng = np.random.default_rng(seed)
    cam = load_rig(EXAMPLES / "rigs" / "mv1440_misaligned.toml").camera
    if seed % 2:
        cam = dataclasses.replace(cam, distortion=(0.0, 0.0, 0.0, 0.0, 0.0))
    uv = rng.uniform(-200, 1600, (200_001, 2))
    uv[:3] = np.nan
    xy = ideal_sensor_from_pixels(uv, cam)
    d = np.column_stack([xy, np.full(len(xy), cam.focal_length_mm)])
    want = d / np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_allclose(camera_dirs(uv, cam), want, rtol=0, atol=2e-16)
    assert np.isnan(camera_dirs(uv[:3], cam)).all()
