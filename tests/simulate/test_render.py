"""The renderer against planted truth: simulate -> measure -> compare with the optics."""
from pathlib import Path

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.optics.trace import trace_pixels
from psvs.simulate.render import render
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.sensor import IDEAL
from psvs.simulate.textures import Checker, Noise, Uniform
from tests.support.scenes import FLAT_LIGHT, centroid, white_disc_scene


def upright(x_mm: float, y_mm: float, z_mm: float) -> Pose:
    """The pose of an unturned object (a rectangle faces the camera) centred at (x, y, z) mm."""
    return Pose(np.eye(3), np.array([x_mm, y_mm, z_mm]))


MISALIGNED = Path(__file__).resolve().parents[2] / "examples" / "rigs" / "misaligned.toml"


@pytest.mark.parametrize("build", [False, True], ids=["designed", "misaligned"])
@pytest.mark.parametrize("x_mm, y_mm, z_mm", [(-20.0, 10.0, 600.0), (60.0, -70.0, 900.0), (-60.0, 40.0, 450.0)])
def test_point_appears_at_its_projection(x_mm, y_mm, z_mm, build):
    """The centroid of a fronto-parallel disc's image is the projection of its centre (exact for a
    pinhole; the plate's non-central left view moves it by << 0.01 px). Both views within 0.05 px, on
    the designed rig and on a misaligned build with a distorting lens (examples/rigs/misaligned.toml). The
    lens bends a disc's image unevenly, which moves its centroid by ~ k1 (r_disc/f)^2 of the field
    position: 0.12 px for a 15 mm disc at the field's edge, so the build is tested with 3 mm discs."""
    rig = load_rig(MISALIGNED) if build else default_rig()
    res = render(white_disc_scene(x_mm, y_mm, z_mm, radius_mm=3.0 if build else 15.0), rig, supersample=4,
                 sensor=IDEAL)
    for view, img in (("left", res.left), ("right", res.right)):
        uv, ok = project_points([[x_mm, y_mm, z_mm]], rig, view)
        assert ok[0]
        assert np.abs(centroid(img, uv[0]) - uv[0]).max() < 0.05


@pytest.mark.parametrize("build", [False, True], ids=["designed", "misaligned"])
def test_truth_disparity_is_the_optics_disparity(build):
    rig = load_rig(MISALIGNED) if build else default_rig()
    scene = Scene((SceneObject("rectangle", upright(0.0, 0.0, 700.0), Checker(15), size_mm=(200.0, 150.0)),),
                  FLAT_LIGHT, 1200.0, Noise(30))
    res = render(scene, rig, supersample=1, sensor=IDEAL, truth=True)
    t = res.truth
    assert t.valid_left.mean() > 0.5 and t.valid_right.mean() > 0.5
    v, u = np.nonzero(t.valid_left)
    pick = np.random.default_rng(0).choice(len(u), 2000, replace=False)
    uv = np.column_stack([u[pick], v[pick]]).astype(float)
    rays = trace_pixels(uv, rig, "left")
    z = t.depth_left_mm[v[pick], u[pick]]
    p = rays.origins_mm + ((z - rays.origins_mm[:, 2]) / rays.dirs[:, 2])[:, None] * rays.dirs
    uv_r, ok = project_points(p, rig, "right")
    assert ok.all()
    np.testing.assert_allclose(t.disparity_left_px[v[pick], u[pick]], uv[:, 0] - uv_r[:, 0], atol=1e-6)
    # the backdrop's part hidden behind the rectangle in the other view has no disparity
    assert (~t.valid_left & np.isfinite(t.depth_left_mm)).any()


@pytest.mark.parametrize("rig_name", ["default", "clear"])
def test_uniform_white_scene_gives_uniform_image(rig_name, clear_rig):
    rig = default_rig() if rig_name == "default" else clear_rig
    wall = SceneObject("rectangle", upright(0.0, 0.0, 800.0), Uniform(1.0), size_mm=(5000.0, 5000.0))
    res = render(Scene((wall,), FLAT_LIGHT), rig, supersample=1, sensor=IDEAL)
    assert np.all(res.image == 255)
    np.testing.assert_allclose(res.irradiance, 1.0, atol=1e-12)


def test_split_ratio_scales_views():
    """split 0.7: the left (transmitted) view carries 0.3 of its light, the right (reflected) 0.7."""
    rig = default_rig().replace(split_ratio=0.7)
    res = render(white_disc_scene(), rig, supersample=1, sensor=IDEAL)
    np.testing.assert_allclose(res.irradiance, 0.3 * res.left + 0.7 * res.right, atol=1e-15)
    for view, share in (("left", 0.3), ("right", 0.7)):
        (u, v), = project_points([[-20.0, 10.0, 600.0]], rig, view)[0].round().astype(int)
        assert res.irradiance[v, u] == pytest.approx(share, abs=1e-12)
        assert abs(int(res.image[v, u]) - 255 * share) <= 0.5 + 1e-9


def pinhole_render(rig, z_rect, size, texture, z_back, back_texture, supersample):
    """Independent pinhole renderer: rays from O1 = (-b/2, 0, -b/2) through (x, y, f), fronto-parallel planes."""
    w, h = rig.camera.image_size_px
    offs = (np.arange(supersample) + 0.5) / supersample - 0.5
    v, u, dv, du = np.meshgrid(np.arange(h, dtype=float), np.arange(w, dtype=float), offs, offs, indexing="ij")
    x = (u + du - rig.camera.principal_point_px[0]) * rig.camera.pixel_pitch_mm[0]
    y = (v + dv - rig.camera.principal_point_px[1]) * rig.camera.pixel_pitch_mm[1]
    f, o1 = rig.camera.focal_length_mm, np.array([-50.0, 0.0, -50.0])
    s = (z_rect - o1[2]) / f
    px, py = o1[0] + s * x, o1[1] + s * y
    inside = (np.abs(px) <= size[0] / 2) & (np.abs(py) <= size[1] / 2)
    sb = (z_back - o1[2]) / f
    bx, by = o1[0] + sb * x, o1[1] + sb * y
    val = np.where(inside, texture(np.column_stack([px.ravel(), py.ravel()])).reshape(px.shape),
                   back_texture(np.column_stack([bx.ravel(), by.ravel()])).reshape(px.shape))
    return val.mean(axis=(2, 3))


def test_zero_plate_left_view_is_a_pinhole_render_from_o1(small_rig):
    rig = small_rig.replace(plate_thickness_mm=0.0)
    tex, back = Noise(8, 2, 0.1, 0.9), Checker(40, 0.2, 0.6)
    scene = Scene((SceneObject("rectangle", upright(0.0, 0.0, 650.0), tex, size_mm=(220.0, 160.0)),),
                  FLAT_LIGHT, 1100.0, back)
    res = render(scene, rig, supersample=3, sensor=IDEAL)
    ref = pinhole_render(rig, 650.0, (220.0, 160.0), tex, 1100.0, back, 3)
    assert np.mean(np.abs(255 * res.left - 255 * ref)) < 0.5


def test_lamp_inverse_square_and_lambert():
    """One white wall, lamp only, at 600 mm = reference: the centre pixel gets exactly `lamp`; at 1200 mm a quarter."""
    rig = default_rig()
    for z, expect in ((600.0, 0.8), (1200.0, 0.2)):
        wall = SceneObject("rectangle", upright(0.0, 0.0, z), Uniform(1.0), size_mm=(4000.0, 4000.0))
        from psvs.simulate.scene import Lighting
        res = render(Scene((wall,), Lighting(0.0, 0.8, (0.0, 0.0, 0.0), 600.0)), rig, supersample=1, sensor=IDEAL)
        (u, v), = project_points([[0.0, 0.0, z]], rig, "right")[0]
        assert res.right[int(round(v)), int(round(u))] == pytest.approx(expect, rel=2e-3)


def test_shadow_is_cast():
    """A box between the lamp (at O) and a wall darkens the wall on the lamp's line through the box; the
    left view (from O1, 50 mm to the side of the lamp) sees that spot past the box."""
    from psvs.simulate.scene import Lighting
    rig = default_rig()
    wall = SceneObject("rectangle", upright(0.0, 0.0, 1000.0), Uniform(1.0), size_mm=(4000.0, 4000.0))
    box = SceneObject("box", upright(-150.0, 0.0, 500.0), Uniform(1.0), size_mm=(20.0, 20.0, 20.0))
    lit = Lighting(0.2, 0.8, (0.0, 0.0, 0.0), 1000.0, True)
    res = render(Scene((wall, box), lit), rig, supersample=1, sensor=IDEAL, truth=True)
    behind = np.array([[-300.0, 0.0, 1000.0]])       # lamp ray through the box centre meets the wall here
    (u, v), = project_points(behind, rig, "left")[0].round().astype(int)
    assert 0 <= u < 640 and 0 <= v < 480
    assert res.truth.depth_left_mm[v, u] == pytest.approx(1000.0)    # the left view sees the wall there
    assert res.left[v, u] == pytest.approx(0.2, abs=1e-9)            # ambient only: in the shadow
    (u2, v2), = project_points([[200.0, 0.0, 1000.0]], rig, "left")[0].round().astype(int)
    assert 0 <= u2 < 640 and res.left[v2, u2] > 0.9


def test_reproducible_noise_and_levels():
    from psvs.simulate.sensor import Sensor, expose
    irr = np.full((200, 200), 0.5)
    s = Sensor(blur_sigma_px=0.0, full_well_e=20000.0, read_noise_e=15.0)
    a, b, c = expose(irr, s, 1), expose(irr, s, 1), expose(irr, s, 2)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    sigma_dn = 255 * np.sqrt(10000 + 15 ** 2) / 20000        # shot + read noise, in grey levels
    assert a.astype(float).std() == pytest.approx(np.sqrt(sigma_dn ** 2 + 1 / 12), rel=0.1)
    assert a.mean() == pytest.approx(127.5, abs=0.2)
    assert np.array_equal(expose(irr, IDEAL), np.full((200, 200), 128, np.uint8))


def test_bad_arguments():
    rig = default_rig()
    with pytest.raises(ValueError, match="supersample must be an integer >= 1"):
        render(white_disc_scene(), rig, supersample=0)
    with pytest.raises(ValueError, match="object 'disc' is behind the rig: it reaches z = 30.0 mm"):
        render(white_disc_scene(z_mm=30.0), rig)
