"""The renderer's kernels (psvs.simulate.kernels) against the NumPy forms they replaced, written out here: the
hits (distance, object, point, normal facing the ray) and the shading (lamp, Lambert, inverse square, shadow
rays), on the rays of a rig through scenes with flat and curved objects, a lamp behind the surfaces and rays
that miss."""
import numpy as np
import pytest
from embreex import mesh_construction, rtcore_scene

from psvs.io.params import load_rig
from psvs.simulate.builtin import builtin_scene, textured, weld_seam
from psvs.simulate.geometry import SceneGeometry
from psvs.simulate.radiance import SHADOW_OFFSET_MM, shade, view_rays
from psvs.simulate.scene import Lighting, Scene


def numpy_hits(geom, o, d, refine):
    """SceneGeometry.intersect's flat-face arithmetic in NumPy (no curved objects in its scenes)."""
    embree = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(embree, geom.triangles.astype(np.float32))
    res = embree.run(o.astype(np.float32), d.astype(np.float32), output=1)
    prim = np.asarray(res["primID"])
    hit = prim >= 0
    safe = np.where(hit, prim, 0)
    nrm = geom.face_normals[safe]
    if refine:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (geom.face_offsets[safe] - np.einsum("ij,ij->i", o, nrm)) / np.einsum("ij,ij->i", d, nrm)
    else:
        t = np.asarray(res["tfar"], dtype=np.float64)
    t[~hit] = np.inf
    obj = np.where(hit, geom.face_owner[safe], -1)
    bad = ~np.isfinite(t) | (t <= 0)
    t[bad], obj[bad] = np.inf, -1
    points = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d
    nrm[np.einsum("ij,ij->i", nrm, d) > 0] *= -1
    return t, obj, points, nrm


def numpy_shade(geom, scene, hits):
    """radiance.shade in NumPy: albedo * (ambient + lamp cos (ref / r)^2 where the lamp is seen), 0 on a miss."""
    light, hit = scene.lighting, hits.obj >= 0
    albedo = np.zeros(len(hits.t_mm))
    for k in np.unique(hits.obj[hit]):
        sel = hits.obj == k
        albedo[sel] = geom.objects[k].texture(geom.local_xy(k, hits.points_mm[sel]))
    irr = np.full(len(albedo), light.ambient)
    p, n = hits.points_mm[hit], hits.normals[hit]
    to_lamp = np.asarray(light.lamp_position_mm) - p
    r = np.linalg.norm(to_lamp, axis=1)
    cos = np.einsum("ij,ij->i", n, to_lamp) / r
    lit = cos > 0
    if light.shadows:
        li = np.flatnonzero(lit)
        start = p[li] + SHADOW_OFFSET_MM * n[li]
        lit[li[geom.occluded(start, to_lamp[li] / r[li, None], r[li] - 2 * SHADOW_OFFSET_MM)]] = False
    irr[hit] += np.where(lit, light.lamp * cos * (light.reference_mm / r) ** 2, 0.0)
    return np.where(hit, albedo * irr, 0.0)


def rays_of(rig_name, n, seed):
    """``n`` of a view's 2 x 2 sample rays drawn at random (the vignetted ones left out)."""
    rays = view_rays(load_rig(rig_name), 2, "left")
    ok = np.flatnonzero(rays.valid)
    pick = np.sort(np.random.default_rng(seed).choice(ok, size=min(n, len(ok)), replace=False))
    return rays.origins_mm[pick], rays.dirs[pick]


@pytest.mark.parametrize("refine", [False, True])
@pytest.mark.parametrize("name", ["weld_seam", "textured", "no backdrop"])
def test_hits_are_numpys(name, refine):
    """Distances, objects and points to 1e-12 relative (the same where NumPy's sums run in the kernel's order),
    normals facing the ray, misses where NumPy has them; on flat faces (meshes, rectangles, boxes, backdrops)."""
    flat = tuple(o for o in textured().objects if o.kind != "sphere")
    scene = {"weld_seam": weld_seam(), "textured": Scene(flat, backdrop_z_mm=1120.0, name="flat"),
             "no backdrop": Scene(flat, name="no backdrop")}[name]
    geom = SceneGeometry(scene)
    o, d = rays_of("default", 20000, 3)
    t, obj, points, nrm = numpy_hits(geom, o, d, refine)
    got = geom.intersect(o, d, refine=refine)
    assert np.array_equal(got.obj, obj)
    if name == "no backdrop":
        assert 0.2 < np.mean(obj < 0) < 0.99           # rays that miss are in the test
    hit = obj >= 0
    assert np.all(np.isinf(got.t_mm[~hit]))
    np.testing.assert_allclose(got.t_mm[hit], t[hit], rtol=1e-12, atol=0)
    np.testing.assert_allclose(got.points_mm, points, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(got.normals[hit], nrm[hit], rtol=0, atol=1e-15)
    assert np.all(np.einsum("ij,ij->i", got.normals[hit], d[hit]) <= 0)


@pytest.mark.parametrize("name", ["weld_seam", "fig6", "lamp behind"])
def test_shading_is_numpys(name):
    """Radiance to 1e-12 relative, in shadow or not as NumPy says (fig6: curved objects and cast shadows); with
    the lamp behind the surfaces only the ambient light; without a lamp only the ambient light."""
    scene = builtin_scene("fig6" if name == "lamp behind" else name)
    if name == "lamp behind":
        scene = Scene(scene.objects, Lighting(0.25, 0.75, (0.0, 0.0, 5000.0), 450.0, True), scene.backdrop_z_mm,
                      scene.backdrop_texture, scene.name)
    geom = SceneGeometry(scene)
    o, d = rays_of("default", 30000, 5)
    hits = geom.intersect(o, d, refine=False)
    got, want = shade(geom, scene, hits), numpy_shade(geom, scene, hits)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    if name == "lamp behind":
        flat = numpy_shade(geom, Scene(scene.objects, Lighting(0.25, 0.0, (0.0, 0.0, 0.0), 450.0, True),
                                       scene.backdrop_z_mm, scene.backdrop_texture, scene.name), hits)
        lit_from_behind = got > flat * (1 + 1e-12)
        assert lit_from_behind.mean() < 0.5      # the lamp far behind lights only faces turned away from the rig
    if name == "fig6":
        light = scene.lighting
        unshadowed = Lighting(light.ambient, light.lamp, light.lamp_position_mm, light.reference_mm, False)
        bright = numpy_shade(geom, Scene(scene.objects, unshadowed, scene.backdrop_z_mm, scene.backdrop_texture,
                                         scene.name), hits)
        assert np.mean(got < bright * (1 - 1e-9)) > 0.01     # shadows are cast on some of the rays drawn
