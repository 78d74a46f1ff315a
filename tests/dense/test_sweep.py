"""Dense depth on rigs drawn as users' cameras would be (issue 40, item 2).

Each draw (tests/support/rig_draws.py) is a camera of 0.3-5 MP with a stock lens and its distortion and
fall-off, the mirrors ``psvs design`` sizes for it, a working range that suits it, a build glued a little
off, a monochrome or a Bayer colour sensor and PNG or JPEG files; it is calibrated from simulated hand-held
card views from its nominal design, as a user would (never handed its true rig). Its scenes
(tests/support/sweep_scenes.py) are photo cards before a wall, a slanted panel, a wall at the far end, a
blank wall and a frame of noise, rendered through the build and read back from the user's files.

Criteria: the calibration within 0.1 mm over the working range (after the rigid motion no image can see);
every textured scene answered (at least one pixel trusted by ``rig_trust``) with at most 10 % (``FAST``:
15 %) of the pixels the right view also sees off by more than 2 % of Z (no answer counts as wrong); every
blank and noise frame refused (no pixel trusted). A failing test prints its draw, with the nominal rig and
the build as TOML, to be replayed from its seed (``calibrated_draw(seed, megapixels)``).

The quick tier is one small draw (with the command line); ``slow`` adds the sweep over larger sizes
(tests/dense/test_sweep_wide.py, a file of its own so that a worker of its own runs it). Both
share the session's cached renders and calibrations (tests/support: every expensive step is cached per
session). What a draw costs on the 2-core host, all five scenes in both modes, CPU seconds: 0.36 MP about 100
(calibration 38 of it), 2.3 MP about 300, 5 MP about 560 (the rays of its 40 million samples alone 110,
calibration 60, each textured scene's render and truth 60); on that host under a load of 3-4 (other
sessions) the quick tier took 125 s of wall time and the slow one's two draws 16 min.
"""
import numpy as np
import pytest

from tests.support.rig_draws import calibrated_draw
from tests.support.sweep_scenes import MAX_BAD, MODES, SCENES, SMALL, check_calibration, check_scene, draw_id, shot

#: The quick tier: seed 1 of the small sensors (752 x 480, 9.6 um, f 16 mm, a Bayer camera writing JPEG).
QUICK = ((1, SMALL),)


@pytest.mark.parametrize("draw", QUICK, ids=draw_id)
def test_draw_calibrates(draw):
    check_calibration(*draw)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("draw", QUICK, ids=draw_id)
def test_scene(draw, scene, mode):
    check_scene(*draw, scene, mode)


def test_support_renders_what_the_renderer_renders():
    """The sweep's shortcuts change no image and no truth, on a window of the quick draw's build (its middle
    third, through its own lens and mirrors): a card view rendered adaptively (2 x 2 samples where the image
    is not smooth, one interpolated where it is) against the renderer's 2 x 2 samples everywhere, within
    5e-6 of full well (a grey level is 4e-3; 1.2e-6 measured); the left view's truth against the renderer's
    ``ground_truth`` (``depth_left_mm`` where ``valid_left``), exactly."""
    from psvs.calibrate.synthetic import random_poses
    from psvs.simulate.geometry import SceneGeometry
    from psvs.simulate.render import ground_truth, render
    from psvs.simulate.sensor import IDEAL
    from tests.support.adaptive import render_irradiance
    from tests.support.rig_draws import card_scene
    from tests.support.sweep_scenes import left_truth, make_scene
    draw = calibrated_draw(*QUICK[0]).draw
    cam = draw.build.camera
    (w, h), (cx, cy) = cam.image_size_px, cam.principal_point_px
    window = draw.build.replace(image_size_px=(w // 3, h // 3), principal_point_px=(cx - w // 3, cy - h // 3))
    pose = random_poses(draw.build, draw.card, 1, seed=5, z_range_mm=draw.card_range_mm, apart=False)[0]
    card = card_scene(draw, pose)
    ours, share = render_irradiance(card, window, adaptive=True)
    theirs = render(card, window, sensor=IDEAL).irradiance
    assert share < 0.9 and np.abs(ours - theirs).max() < 5e-6
    scene = make_scene(draw, "cards")
    geom = SceneGeometry(scene)
    truth = ground_truth(scene, window, geom)
    np.testing.assert_array_equal(left_truth(scene, window, geom),
                                  np.where(truth.valid_left, truth.depth_left_mm, np.nan))


@pytest.fixture(scope="module")
def user_files(tmp_path_factory):
    """The quick draw as a user's files: the nominal rig ``psvs design --rig-out`` writes from the camera
    and the mirror positions, the calibrated rig file (``psvs calibrate`` writes the nominal file with the
    calibrated values in it), and the frames of the scenes."""
    from psvs.io.params import dumps_rig
    from psvs.optics.rig import MIRROR_NAMES
    from tests.support.cli import run
    cal = calibrated_draw(*QUICK[0])
    folder = tmp_path_factory.mktemp("user")
    bare = folder / "camera.toml"
    bare.write_text(dumps_rig(cal.draw.nominal.with_extents({n: None for n in MIRROR_NAMES})))
    return folder, bare, cal, run


def test_design_from_the_command_line(capsys, user_files):
    """``psvs design --rig-out`` on the user's camera and mirror positions (with the pupil's margin) writes
    the nominal rig the draw designed: the same mirror sizes, layout clear (exit 0)."""
    from psvs.io.params import load_rig
    folder, bare, cal, run = user_files
    nominal = cal.draw.nominal
    margin = cal.draw.margin_mm
    out = folder / "nominal.toml"
    code, text, err = run(capsys, "design", "--rig", str(bare), "--margin-mm", f"{margin!r}", "--rig-out", str(out),
                          "--no-search")
    assert code == 0, text + err
    assert "Layout: clear" in text
    got = load_rig(out)
    for name in ("m1", "m2", "m3", "m4"):
        np.testing.assert_allclose(got.mirrors.extent(name).along_mm, nominal.mirrors.extent(name).along_mm, atol=1e-9)
        np.testing.assert_allclose(got.mirrors.extent(name).height_mm, nominal.mirrors.extent(name).height_mm,
                                   atol=1e-9)


@pytest.mark.parametrize("scene", ["cards", "blank"])
def test_disparity_from_the_command_line(capsys, user_files, scene):
    """``psvs disparity FRAME --rig CALIBRATED.toml --depth D.npy`` on the user's file: a textured scene exits
    0 with the depth written (on the left view's rectified grid, right within the criterion where the echo
    is trusted and elsewhere); a blank wall exits 1 with 'cannot measure' and writes nothing."""
    from psvs.io.params import save_rig
    from psvs.optics.search_range import rectification_for
    from tests.support.sweep_scenes import truth_on_left_grid
    folder, bare, cal, run = user_files
    rig_file = folder / "calibrated.toml"
    save_rig(cal.rig, rig_file, template=bare.read_text())
    s = shot(QUICK[0][0], scene, QUICK[0][1])
    disp, depth = folder / f"{scene}_d.npy", folder / f"{scene}_z.npy"
    code, text, err = run(capsys, "disparity", str(s.path), "--rig", str(rig_file), "--near-mm",
                          f"{cal.draw.near_mm:g}", "--far-mm", f"{cal.draw.far_mm:g}", "-o", str(disp), "--depth",
                          str(depth))
    if scene == "blank":
        assert code == 1 and "cannot measure" in err, (code, text, err)
        assert not disp.exists() and not depth.exists()
        return
    assert code == 0, f"{err}\n{cal.describe()}"
    z = np.load(depth)
    rect = rectification_for(cal.rig, cal.draw.near_mm, cal.draw.far_mm)
    truth = truth_on_left_grid(s.truth_mm, rect, z.shape)
    ok = np.isfinite(truth)
    bad = float(np.mean(~(np.abs(z[ok] - truth[ok]) <= 0.02 * truth[ok])))
    assert bad <= MAX_BAD["default"], f"{bad:.1%} wrong\n{cal.describe()}"
