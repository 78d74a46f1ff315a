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
from psvs.simulate.textures import ImageTexture, Noise


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


def numpy_bilinear(image, size_mm, xy):
    """ImageTexture's bilinear read in NumPy, clamped to the edge pixels."""
    h, w = image.shape
    u = np.clip((xy[:, 0] / size_mm[0] + 0.5) * w - 0.5, 0, w - 1)
    v = np.clip((xy[:, 1] / size_mm[1] + 0.5) * h - 0.5, 0, h - 1)
    u0 = np.minimum(np.floor(u).astype(int), w - 2) if w > 1 else np.zeros(len(u), int)
    v0 = np.minimum(np.floor(v).astype(int), h - 2) if h > 1 else np.zeros(len(v), int)
    fu, fv = u - u0, v - v0
    u1, v1 = np.minimum(u0 + 1, w - 1), np.minimum(v0 + 1, h - 1)
    top = image[v0, u0] * (1 - fu) + image[v0, u1] * fu
    bot = image[v1, u0] * (1 - fu) + image[v1, u1] * fu
    return top * (1 - fv) + bot * fv


@pytest.mark.parametrize("shape", [(7, 5), (1, 9), (6, 1), (1, 1), (300, 410)])
def test_image_texture_reads_as_numpy_bilinear(shape):
    """ImageTexture at points inside, on and beyond its edges (clamped), on images of one row or column too; a
    pixel centre reads its pixel exactly."""
    rng = np.random.default_rng(sum(shape))
    image, size = rng.random(shape), (40.0, 30.0)
    tex = ImageTexture(image, size)
    xy = rng.uniform(-30, 30, (5000, 2))
    np.testing.assert_allclose(tex(xy), numpy_bilinear(image, size, xy), rtol=1e-14, atol=0)
    h, w = shape
    r, c = h // 2, w // 2                            # a pixel's centre in local mm
    centre = np.array([[((c + 0.5) / w - 0.5) * size[0], ((r + 0.5) / h - 0.5) * size[1]]])
    assert tex(centre)[0] == pytest.approx(image[r, c], abs=1e-12)
    assert np.isnan(tex(np.array([[np.nan, 0.0], [0.0, np.inf]]))).all()       # nothing read out of the image


def test_noise_is_the_smoothstep_interpolation_of_its_lattice():
    """Noise against the formula in NumPy (negative coordinates wrap with the lattice's 1024 period); on a
    lattice node it is the node's value between low and high."""
    tex = Noise(scale_mm=3.0, seed=11, low=0.2, high=0.7)
    xy = np.random.default_rng(2).uniform(-5000, 5000, (5000, 2))
    g = xy / 3.0
    i = np.floor(g)
    f = g - i
    f = f * f * (3 - 2 * f)
    i = i.astype(np.int64) & 1023
    lat = np.random.default_rng(11).random((1024, 1024))
    ix, iy, ix1, iy1 = i[:, 0], i[:, 1], (i[:, 0] + 1) & 1023, (i[:, 1] + 1) & 1023
    top = lat[iy, ix] * (1 - f[:, 0]) + lat[iy, ix1] * f[:, 0]
    bot = lat[iy1, ix] * (1 - f[:, 0]) + lat[iy1, ix1] * f[:, 0]
    np.testing.assert_allclose(tex(xy), 0.2 + 0.5 * (top * (1 - f[:, 1]) + bot * f[:, 1]), rtol=1e-14, atol=0)
    node = np.array([[3.0 * 5, 3.0 * -2]])
    assert tex(node)[0] == pytest.approx(0.2 + 0.5 * lat[-2 & 1023, 5], abs=1e-14)
    assert np.isnan(tex(np.array([[np.nan, 0.0], [0.0, -np.inf]]))).all()


def test_a_ray_along_its_face_is_a_miss_not_an_error():
    """A ray in the plane of the face Embree names (0 / 0 in the ray-plane distance) and a lamp on the hit point
    (0 / 0 in the cosine) give NaN as NumPy did, not ZeroDivisionError; the hit then counts as a miss."""
    from psvs.simulate.kernels import face_hits, finish_hits, lamp_rays
    normals, offsets, owner = np.array([[0.0, 0.0, 1.0]]), np.array([500.0]), np.array([0])
    o, d = np.array([[0.0, 0.0, 500.0]]), np.array([[1.0, 0.0, 0.0]])
    t, obj, nrm = face_hits(np.array([0], np.int32), np.array([3.0], np.float32), normals, offsets, owner, o, d,
                            True)
    assert np.isnan(t[0]) and obj[0] == 0
    finish_hits(t, obj, nrm, o, d)
    assert np.isinf(t[0]) and obj[0] == -1
    r2, cos, lit, *_ = lamp_rays(np.zeros((1, 3)), np.array([[0.0, 0.0, -1.0]]), np.array([True]), np.zeros(3), 0.1)
    assert r2[0] == 0 and np.isnan(cos[0]) and len(lit) == 0
