import numpy as np
import pytest

from psvs.simulate.geometry import SceneGeometry
from psvs.simulate.scene import Pose, Scene, SceneObject


@pytest.fixture(scope="module")
def scene_and_rays():
    objs = (SceneObject("sphere", Pose(np.eye(3), np.array([150.0, 0.0, 600.0])), radius_mm=40),
            SceneObject("cylinder", Pose.from_euler_deg([-150, 0, 600.0], [90, 0, 0]), radius_mm=30, height_mm=80),
            SceneObject("disc", Pose.from_euler_deg([0, 150, 700.0], [0, 30, 0]), radius_mm=30),
            SceneObject("box", Pose.from_euler_deg([0, -150, 650.0], [10, 20, 30]), size_mm=(50.0, 40.0, 30.0)))
    scene = Scene(objs, backdrop_z_mm=1500.0)
    rng = np.random.default_rng(0)
    n = 300_000
    d = np.column_stack([rng.uniform(-0.4, 0.4, n), rng.uniform(-0.4, 0.4, n), np.ones(n)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return scene, SceneGeometry(scene).intersect(np.zeros((n, 3)), d), d


def test_hits_lie_on_the_true_surfaces(scene_and_rays):
    scene, h, _ = scene_and_rays
    s = h.points_mm[h.obj == 0] - [150, 0, 600]
    assert np.abs(np.linalg.norm(s, axis=1) - 40).max() < 1e-9
    c = scene.objects[1].pose.to_local(h.points_mm[h.obj == 1])
    on_side = np.abs(np.hypot(c[:, 0], c[:, 1]) - 30)
    on_cap = np.abs(np.abs(c[:, 2]) - 40)
    assert np.minimum(on_side, on_cap).max() < 1e-9
    dl = scene.objects[2].pose.to_local(h.points_mm[h.obj == 2])
    assert np.abs(dl[:, 2]).max() < 1e-9 and np.hypot(dl[:, 0], dl[:, 1]).max() <= 30 + 1e-9
    bl = scene.objects[3].pose.to_local(h.points_mm[h.obj == 3])
    assert (np.abs(np.abs(bl) - [25, 20, 15]) < 1e-9).any(axis=1).all()   # on a face of the box
    assert np.abs(h.points_mm[h.obj == 4][:, 2] - 1500).max() < 1e-9        # backdrop


def test_curved_outlines_are_exact(scene_and_rays):
    """Rays are classified by the analytic surfaces, not their tessellation: compare with closed forms."""
    scene, h, d = scene_and_rays
    # sphere: the ray meets it iff its distance from the centre is <= r
    c = np.array([150.0, 0.0, 600.0])
    dist = np.linalg.norm(np.cross(d, c), axis=1)
    assert np.array_equal(h.obj == 0, dist <= 40)
    # disc (tilted 30 deg about y): nothing stands in front of it
    disc = scene.objects[2]
    n = disc.pose.rotation[:, 2]
    t = (disc.pose.position_mm @ n) / (d @ n)
    loc = disc.pose.to_local(t[:, None] * d)
    assert np.array_equal(h.obj == 2, np.hypot(loc[:, 0], loc[:, 1]) <= 30)


def test_normals_face_the_rays(scene_and_rays):
    _, h, d = scene_and_rays
    assert (np.einsum("ij,ij->i", h.normals, d) <= 0).all()
    np.testing.assert_allclose(np.linalg.norm(h.normals, axis=1), 1.0, atol=1e-12)


def test_misses_are_flagged():
    g = SceneGeometry(Scene((SceneObject("sphere", Pose(np.eye(3), np.array([0.0, 0.0, 500.0])), radius_mm=10),)))
    h = g.intersect(np.zeros((2, 3)), np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))
    assert h.obj.tolist() == [0, -1] and h.t_mm[0] == pytest.approx(490.0) and np.isinf(h.t_mm[1])
