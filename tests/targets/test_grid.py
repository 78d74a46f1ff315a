"""Circle grids in complex images and the generic OpenCV stereo calibration (shared intrinsics, R, T)."""
import numpy as np
import pytest

from psvs import default_rig
from psvs.optics.project import project_points
from psvs.simulate.builtin import regulated_light
from psvs.simulate.render import render
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.textures import CircleGrid, Uniform
from psvs.targets.grid import calibrate_stereo, detect_grid

TEX = CircleGrid(4, 5, 15.0, 7.0)
POSES = ((550, 10, -15, -5, 10), (650, -15, 10, 5, -20), (750, 20, 20, 0, 0), (600, 0, -25, 10, 15),
         (700, -10, 0, -10, -10), (800, 15, -10, 0, 20))


def grid_scene(z, rx, ry, x, y):
    sheet = SceneObject("rectangle", Pose.from_euler_deg([x, y, z], [rx, ry, 0]), TEX, size_mm=(90.0, 70.0))
    return Scene((sheet,), regulated_light(z), z + 400, Uniform(0.08)), sheet


@pytest.fixture(scope="module")
def detections():
    rig = default_rig()
    out = []
    for pose in POSES:
        scene, sheet = grid_scene(*pose)
        out.append((detect_grid(render(scene, rig, seed=pose[0]).image, 4, 5), sheet))
    return out


def test_grid_points_pair_across_views(detections):
    """Every detected left/right pair is one disc: its exact projections match within 0.1 px."""
    rig = default_rig()
    for det, sheet in detections:
        centres = sheet.pose.to_world(np.column_stack([TEX.centres_mm(), np.zeros(20)]))
        for view, pts in (("left", det.left), ("right", det.right)):
            uv, _ = project_points(centres, rig, view)
            d = np.linalg.norm(pts[:, None, :] - uv[None, :, :], axis=2).min(axis=1)
            assert d.max() < 0.1
        assert np.all(det.left[:, 0] > det.right[:, 0])
        assert np.abs(det.left[:, 1] - det.right[:, 1]).max() < 1.0


def test_generic_stereo_calibration(detections):
    """Shared-intrinsics pinhole stereo (OpenCV): T ~ (-(b + m), 0, 0) with m ~ 1 mm the plate's shift, R ~ I,
    f within 1.5 %. The plate makes the left view non-central, which this generic model cannot hold exactly
    (the sweep calibration on the exact optics does)."""
    cal = calibrate_stereo([d for d, _ in detections], 4, 5, 15.0, (640, 480))
    assert cal.rms_intrinsics_px < 0.1 and cal.rms_stereo_px < 0.1
    assert abs(cal.K[0, 0] - 1130.0) < 0.015 * 1130.0
    assert abs(-cal.T[0] - 101.0) < 1.5 and abs(cal.T[1]) < 0.5
    assert np.abs(cal.R - np.eye(3)).max() < 1e-3


def test_grid_errors():
    rig = default_rig()
    blank = np.full((480, 640), 60, np.uint8)
    with pytest.raises(ValueError, match=r"found 0 disc\(s\), expected 40"):
        detect_grid(blank, 4, 5)
    wide = SceneObject("rectangle", Pose.from_euler_deg([0, 0, 600], [0, 0, 0]), CircleGrid(3, 9, 15.0, 7.0),
                       size_mm=(150.0, 50.0))
    img = render(Scene((wide,), regulated_light(600), 1000, Uniform(0.08)), rig, seed=1).image
    with pytest.raises(ValueError, match=r"interleave|found \d+ disc\(s\), expected 54"):
        detect_grid(img, 3, 9)
    with pytest.raises(ValueError, match="needs at least 3 grid poses"):
        calibrate_stereo([], 4, 5, 15.0, (640, 480))
    with pytest.raises(ValueError, match="diameter_mm must be < spacing_mm"):
        CircleGrid(4, 5, 10.0, 12.0)


def test_chessboard_views_in_a_complex_image():
    """Both superimposed copies of a chessboard are found (OpenCV, one after the other) and paired corner by
    corner: within 0.6 px of the exact projections (cornerSubPix on a complex image; circle grids reach
    ~0.03 px, so they are the better calibration target in complex images)."""
    from psvs.simulate.textures import Chessboard
    from psvs.targets.grid import detect_chessboard
    rig = default_rig()
    board = Chessboard(6, 5, 10.0)
    for z, rx, ry in ((600, 10, -15), (750, -15, 20)):
        sheet = SceneObject("rectangle", Pose.from_euler_deg([0, 0, z], [rx, ry, 0]), board, size_mm=(80.0, 70.0))
        img = render(Scene((sheet,), regulated_light(z), z + 400, Uniform(0.1)), rig, seed=z).image
        det = detect_chessboard(img, 4, 5)
        j, i = np.meshgrid(np.arange(-2, 3), np.arange(-1.5, 2.5))
        corners = sheet.pose.to_world(np.column_stack([j.ravel() * 10.0, i.ravel() * 10.0, np.zeros(20)]))
        for view, pts in (("left", det.left), ("right", det.right)):
            uv, _ = project_points(corners, rig, view)
            assert np.linalg.norm(pts - uv, axis=1).max() < 0.6
    with pytest.raises(ValueError, match=r"found 0 of the 2 views of a 4x5 chessboard"):
        detect_chessboard(np.full((480, 640), 60, np.uint8), 4, 5)
