import numpy as np
import pytest

from psvs.optics.project import project_points
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
