"""Calibration of the mv1440 build from hand-held views: planted truth at 1440 x 1080 px, 3.45 um.

The images are rendered through src/psvs/rigs/mv1440_misaligned.toml (mirrors 0.1-0.25 deg and up to
0.5 mm off, the box turned, the lens as built); calibration starts from the nominal design (mv1440). A 5x7
card of 16 mm (103 mm wide) is wider than its disparity at every depth held (400-900 mm): its two views
interleave in every one of the 20 views, and discs of the two views touch or merge in several; the split
along u (psvs.targets.grid.detect_grid, what calibrate used before psvs.targets.detect) refuses all 20
('the grid's two views interleave', 'found 53-66 disc(s), expected 70'; a user's 5x7 card lost 7 of 20).
OpenCV's asymmetric circle grid and a ChArUco board calibrate too."""
import numpy as np
import pytest

from psvs.calibrate.folder import calibrate_folder
from psvs.calibrate.synthetic import random_poses, render_grid_shots
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.rigs import shipped_rig_path
from psvs.simulate.textures import AsymmetricCircleGrid, CharucoBoard, CircleGrid
from psvs.targets.target_file import dumps_target
from psvs.targets.target_points import target_points_mm
from tests.support.geometry import reconstruction_errors

pytestmark = pytest.mark.slow

NOMINAL, BUILD = (load_rig(shipped_rig_path(n)) for n in ("mv1440", "mv1440_misaligned"))


def folder_of(tmp_path_factory, target, views, seed, margin_px=12.0):
    """Views of a hand-held target at 400-900 mm through the build; the folder and how many interleave."""
    folder = tmp_path_factory.mktemp(type(target).__name__)
    poses = random_poses(BUILD, target, views, seed=seed, z_range_mm=(400.0, 900.0), margin_px=margin_px,
                         apart=False)
    interleaved = 0
    local = target_points_mm(target)
    for k, shot in enumerate(render_grid_shots(BUILD, target, poses, seed=seed)):
        write_png(folder / f"card_{k:02d}.png", shot.image)
        pts = poses[k].to_world(np.column_stack([local, np.zeros(len(local))]))
        left, right = (project_points(pts, BUILD, v)[0] for v in ("left", "right"))
        interleaved += int(left[:, 0].min() < right[:, 0].max())
    (folder / "target.toml").write_text(dumps_target(target))
    return folder, interleaved


@pytest.fixture(scope="module")
def circles(tmp_path_factory):
    folder, interleaved = folder_of(tmp_path_factory, CircleGrid(5, 7, 16.0, 7.0), 20, seed=1)
    return calibrate_folder(folder, NOMINAL), interleaved


def test_interleaving_card_views_calibrate_the_build(circles):
    """Acceptance: of 20 hand-held views, all interleaving, at least 18 used; RMS <= 0.05 px; true
    correspondences over 400-1200 mm triangulate within 0.1 mm mean after the rigid motion no image can fix
    (docs/calibration.md, 'What images cannot see'); the lens's k1 and f within 4 sigma."""
    res, interleaved = circles
    assert interleaved == 20
    assert len(res.used) >= 18, res.skipped
    b = res.bundle
    assert b.success and b.rms_px <= 0.05 and max(b.rms_by_image.values()) <= 0.1
    _, aligned, pts = reconstruction_errors(res.rig, BUILD)
    assert len(pts) > 300 and np.mean(aligned) <= 0.1
    for name, want in (("k1", BUILD.camera.distortion[0]), ("focal_length_mm", BUILD.camera.focal_length_mm)):
        assert abs(b.values[name] - want) < 4 * b.sigma[name] + 1e-9, (name, b.values[name], want)


def test_asymmetric_grid_calibrates(tmp_path_factory):
    """OpenCV's asymmetric grid (7 rows of 4 discs, 9 mm): 12 views, another seed, all used; within 0.15 mm."""
    folder, _ = folder_of(tmp_path_factory, AsymmetricCircleGrid(7, 4, 9.0, 7.0), 12, seed=5)
    res = calibrate_folder(folder, NOMINAL)
    assert len(res.used) == 12, res.skipped
    assert res.bundle.rms_px <= 0.05
    _, aligned, _ = reconstruction_errors(res.rig, BUILD)
    assert np.mean(aligned) <= 0.15


def test_charuco_board_calibrates(tmp_path_factory):
    """A 6x4 ChArUco board (14 mm squares, 10 mm DICT_4X4_50 markers): 12 views, its markers paired by id;
    OpenCV's corners on a complex image are a few tenths of a pixel off (the discs' a few hundredths), so the
    reconstruction is looser: within 1 mm (0.47 mm measured on another seed's 12 views)."""
    folder, _ = folder_of(tmp_path_factory, CharucoBoard(6, 4, 14.0, 10.0), 12, seed=6, margin_px=40.0)
    res = calibrate_folder(folder, NOMINAL)
    assert len(res.used) >= 10, res.skipped
    assert res.bundle.rms_px <= 0.3
    _, aligned, _ = reconstruction_errors(res.rig, BUILD)
    assert np.mean(aligned) <= 1.0


@pytest.mark.parametrize("seed", [2, 3])
def test_every_interleaving_view_is_read(tmp_path_factory, seed):
    """Other poses (two more seeds, 10 views each at 400-900 mm): every view is read through the nominal
    design (at least 28 of the 35 discs paired), trusted points within 0.15 px of the build's exact
    projections and with their own ids (up to a shift along the card where detect_target says the ids are
    uncertain); at least 9 of the 10 views with the 6 trusted points calibrate uses (seed 2's view 9 has 5:
    most of its discs lie on the other copy's card edge or touch the other view's; calibrate skips it,
    saying to turn the card)."""
    from psvs.io.images import read_grey
    from psvs.targets.detect import detect_target
    card = CircleGrid(5, 7, 16.0, 7.0)
    folder, interleaved = folder_of(tmp_path_factory, card, 10, seed=seed)
    assert interleaved == 10
    poses = random_poses(BUILD, card, 10, seed=seed, z_range_mm=(400.0, 900.0), apart=False)
    local = np.column_stack([card.centres_mm(), np.zeros(35)])
    usable = 0
    for k, pose in enumerate(poses):
        det = detect_target(read_grey(folder / f"card_{k:02d}.png"), card, NOMINAL)
        tl, tr = (project_points(pose.to_world(local), BUILD, v)[0] for v in ("left", "right"))
        t = det.reliable
        assert len(det.ids) >= 28 and t.sum() >= 1, k
        usable += int(t.sum() >= 6)
        row, col = np.divmod(det.ids[t], 7)
        moves = [(0, 0)] if det.ids_certain else [(r, c) for r in range(-2, 3) for c in range(-3, 4)
                                                  if (0 <= row + r).all() and (row + r < 5).all()
                                                  and (0 <= col + c).all() and (col + c < 7).all()]
        err = min(max(np.abs(det.left[t] - tl[(row + r) * 7 + col + c]).max(),
                      np.abs(det.right[t] - tr[(row + r) * 7 + col + c]).max()) for r, c in moves)
        assert err < 0.15, (k, err)
    assert usable >= 9
