import numpy as np
import pytest

from psvs.optics.project import project_points
from psvs.simulate.render import render
from psvs.simulate.sensor import IDEAL
from psvs.simulate.sequence import render_sequence, scene_in_rig_frame, straight_path
from tests.support.scenes import white_disc_scene


def test_moving_the_rig_moves_the_image(small_rig):
    """Rig moved +10 mm in X: the disc at Z = 600 moves by -f 10 / (Z + b/2) / pitch in both views."""
    scene = white_disc_scene(0.0, 0.0, 600.0, 20.0)
    frames = list(render_sequence(scene, small_rig, straight_path([0, 0, 0], [10, 0, 0], 2), supersample=2,
                                  sensor=IDEAL))
    assert len(frames) == 2
    shift = -11.3 * 10 / 650 / 0.04
    for view in ("left", "right"):
        (u0, v0), = project_points([[0.0, 0.0, 600.0]], small_rig, view)[0]
        a, b = (getattr(f, view) for f in frames)
        ua = (a * np.arange(160)).sum() / a.sum()
        ub = (b * np.arange(160)).sum() / b.sum()
        assert ub - ua == pytest.approx(shift, abs=0.05)


def test_identity_pose_keeps_the_scene(small_rig):
    scene = white_disc_scene()
    moved = scene_in_rig_frame(scene, np.eye(4))
    assert moved.backdrop_z_mm is None and moved.objects[-1].name == "backdrop"
    np.testing.assert_allclose(moved.objects[0].pose.position_mm, scene.objects[0].pose.position_mm)


def test_bad_frames():
    with pytest.raises(ValueError, match="frames must be >= 1"):
        straight_path([0, 0, 0], [1, 0, 0], 0)


def test_a_moved_geometry_is_the_moved_scenes(small_rig):
    """A rigid scene seen from a moving rig: its geometry built once and moved (MovedGeometry) gives the hits, the
    occlusions, the front and the rendered frames of the geometry built for each pose (curved objects, a mesh, a
    backdrop), to float64's rounding; a geometry of another scene is refused."""
    from scipy.spatial.transform import Rotation

    from psvs.simulate.builtin import weld_seam
    from psvs.simulate.geometry import SceneGeometry
    from psvs.simulate.scene import Pose, Scene, SceneObject
    from psvs.simulate.sequence import render_from
    from psvs.transforms import transform_from
    seam = weld_seam(distance_mm=420.0, width_mm=60.0, length_mm=80.0)
    scene = Scene(seam.objects + (SceneObject("sphere", Pose(np.eye(3), np.array([40.0, 10.0, 560.0])), radius_mm=25),
                                  SceneObject("disc", Pose.from_euler_deg([-50, -20, 520.0], [0, 25, 0]),
                                              radius_mm=20)),
                  seam.lighting, 900.0)
    base = SceneGeometry(scene)
    rng = np.random.default_rng(3)
    n = 20_000
    o = rng.uniform(-20, 20, (n, 3))
    d = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), np.ones(n)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for k in range(3):
        turn = rng.uniform(-0.15, 0.15, 3) if k else np.zeros(3)     # (a turned backdrop reaches behind the rig)
        T = transform_from(Rotation.from_rotvec(turn).as_matrix(), rng.uniform(-30, 30, 3))
        moved = scene_in_rig_frame(scene, T)
        fresh, posed = SceneGeometry(moved), base.moved(T, moved.objects)
        a, b = fresh.intersect(o, d), posed.intersect(o, d)
        hit = a.obj >= 0
        assert hit.mean() > 0.5 and np.mean(a.obj == b.obj) > 0.999
        same = hit & (a.obj == b.obj)
        np.testing.assert_allclose(b.points_mm[same], a.points_mm[same], atol=1e-6)
        np.testing.assert_allclose(b.normals[same], a.normals[same], atol=1e-6)
        dist = np.where(hit, a.t_mm, 100.0) - 1.0
        assert np.mean(fresh.occluded(o, d, dist) == posed.occluded(o, d, dist)) > 0.999
        assert [posed.min_z_mm(j) for j in range(len(moved.objects))] == pytest.approx(
            [fresh.min_z_mm(j) for j in range(len(moved.objects))], abs=1e-9)
        if k == 0:
            whole = render(moved, small_rig, supersample=1, sensor=IDEAL)
            again = render_from(scene, T, small_rig, base, supersample=1, sensor=IDEAL)
            assert np.mean(np.abs(again.left - whole.left) > 1e-6) < 1e-3
            assert np.abs(again.image.astype(int) - whole.image.astype(int)).max() <= 1
    with pytest.raises(ValueError, match="the moved scene has 1 objects, its geometry 5"):
        base.moved(np.eye(4), scene.objects[:1])
