"""The paper's accuracy pattern (Fig. 9) in rendered complex images, measured with the known rig
(nothing calibrated: these are the measurement's own errors)."""
import json

import numpy as np
import pytest

from psvs import default_rig
from psvs.accuracy.pattern_measure import measure_pattern
from psvs.errors import MeasurementError
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from psvs.targets.pattern import detect_pattern
from tests.support.cli import EXAMPLE, run

CASES = [(440, 0), (589, 0), (736, 10), (883, 0), (1000, -15), (1123, 0)]


@pytest.fixture(scope="module")
def images():
    rig = default_rig()
    return {c: render(builtin_scene(f"fig9:distance_mm={c[0]},tilt_y_deg={c[1]}"), rig, seed=3).image for c in CASES}


def test_centres_at_the_true_projections_even_when_straddling(images):
    """At 440 mm and at 736 mm tilted, circles straddle the band where both views' sheets overlap (the
    background changes under part of a circle). Circles clear of the band: within 0.1 px (sensor noise
    included) of the exact projection of their centre. Straddling ones: within 0.25 px. Known limitation:
    when the other sheet's border runs close along the rim it biases many rays alike; masking that border
    is the next step."""
    rig = default_rig()
    for dist, tilt in ((440, 0), (736, 10)):
        sheet = builtin_scene(f"fig9:distance_mm={dist},tilt_y_deg={tilt}").objects[0]
        true = sheet.pose.to_world(np.column_stack([sheet.texture.centres_mm(), np.zeros(5)]))
        det = detect_pattern(images[(dist, tilt)])
        for view, ells in (("left", det.left), ("right", det.right)):
            uv, _ = project_points(true, rig, view)
            err = np.abs(np.array([e.centre_px for e in ells]) - uv).max(axis=1)
            assert err.max() < 0.25 and np.sort(err)[-2] < 0.1, (dist, view, err)


def test_table1_columns(images):
    """Measured with the known rig at 440-1123 mm, flat and tilted: |Z error| <= 0.5 mm (mean <= 0.2),
    diameter error <= 0.1 mm mean, first-last distance (80 mm) error <= 0.1 mm mean. (The paper: 2.50 mm,
    0.145 mm and 0.72 mm mean.)"""
    rig = default_rig()
    z, d, a = [], [], []
    for (dist, tilt), img in images.items():
        m = measure_pattern(img, rig)
        z.append(m.Z_mm - dist)
        d.append(m.diameter_mm - 10.0)
        a.append(m.first_last_distance_mm - 80.0)
    z, d, a = map(np.abs, (np.array(z), np.array(d), np.array(a)))
    assert z.max() <= 0.5 and z.mean() <= 0.2
    assert d.mean() <= 0.1 and a.mean() <= 0.1


@pytest.mark.parametrize("dist, tilt", [(470, 0), (760, 8), (1050, -6)])
def test_diameters_on_a_misaligned_build(dist, tilt):
    """On a build (mirrors tilted and shifted, distorting lens, rows of the two views 3-16 px apart) a rim
    point's twin lies on its epipolar curve, not on its row: the circles still measure 10 mm (they
    used to be NaN), measured with the build's own rig."""
    rig = load_rig("misaligned")
    img = render(builtin_scene(f"fig9:distance_mm={dist},tilt_y_deg={tilt}"), rig, seed=dist).image
    m = measure_pattern(img, rig)
    assert np.all(np.isfinite(m.diameters_mm))
    assert np.abs(m.diameters_mm - 10.0).max() <= 0.25 and abs(m.diameter_mm - 10.0) <= 0.1   # as on the ideal rig
    assert abs(m.first_last_distance_mm - 80.0) <= 0.25


def test_bad_images():
    rig = default_rig()
    with pytest.raises(ValueError, match="image is blank"):
        measure_pattern(np.full((480, 640), 40, np.uint8), rig)
    off = render(builtin_scene("fig9:distance_mm=700,x_mm=250"), rig, seed=1).image   # partly out of view
    with pytest.raises(MeasurementError, match=r"found 3 circle\(s\), expected 10 \(5 per view\)"):
        measure_pattern(off, rig)
    # one circle missing: a sheet with four circles
    from dataclasses import replace
    scene = builtin_scene("fig9:distance_mm=700")
    sheet = scene.objects[0]
    four = replace(scene, objects=(replace(sheet, texture=replace(sheet.texture, count=4)),))
    with pytest.raises(MeasurementError, match=r"found 8 circle\(s\), expected 10"):
        measure_pattern(render(four, rig, seed=1).image, rig)


def test_a_pattern_before_a_striped_wall_names_the_background(tmp_path):
    """An adversarial trial (2026-12-06): the pattern at 800 mm, wholly in view and in range, before a wall of
    vertical stripes (30 px) was refused as "a circle is missing or the pattern is partly out of view": the
    stripes' edges run into the circles' outlines. The refusal now names that cause too."""
    from psvs.io.scene_file import load_scene
    x = np.arange(1600)
    write_png(tmp_path / "stripes.png", np.tile(np.where((x // 15) % 2 == 0, 230, 20).astype(np.uint8), (1200, 1)))
    scene = tmp_path / "scene.toml"
    scene.write_text('name = "pattern_on_stripes"\n[backdrop]\nz_mm = 1050\ntexture = { type = "image", file = '
                     '"stripes.png", size_mm = [1600, 1200] }\n[[objects]]\ntype = "rectangle"\n'
                     'size_mm = [120, 50]\nposition_mm = [0, 0, 800]\ntexture = { type = "circles", diameter_mm = 10, '
                     'spacing_mm = 20, count = 5, low = 0.05, high = 0.9 }\n')
    image = render(load_scene(scene), default_rig(), seed=1).image
    with pytest.raises(MeasurementError, match=r"expected 10 \(5 per view\): .*run into what lies behind them"):
        measure_pattern(image, default_rig())


def test_cli(capsys, tmp_path, images):
    path = tmp_path / "p.png"
    write_png(path, images[(589, 0)])
    code, out, _ = run(capsys, "measure", "circles", str(path), "--rig", EXAMPLE, "--json")
    data = json.loads(out)
    assert code == 0 and abs(data["Z_mm"] - 589) < 0.5 and len(data["diameters_mm"]) == 5
    code, _, err = run(capsys, "measure", "circles", str(path), "--rig", EXAMPLE, "--count", "0")
    assert code == 2 and "count must be an integer >= 2" in err
    blank = tmp_path / "b.png"
    write_png(blank, np.full((480, 640), 40, np.uint8))
    code, _, err = run(capsys, "measure", "circles", str(blank), "--rig", EXAMPLE)
    assert code == 2 and "image is blank" in err
    # trial 45: a dark 16-bit file (3..63 of a 10-bit depth) was "blank (no contrast)", exit 2; it is too dark
    # to tell the pattern, exit 1, its grey levels named
    import cv2
    dark = tmp_path / "dark16.png"
    assert cv2.imwrite(str(dark), (images[(589, 0)] // 4).astype(np.uint16))
    code, _, err = run(capsys, "measure", "circles", str(dark), "--rig", EXAMPLE)
    assert code == 1 and len(err.strip().splitlines()) == 1, err
    assert "contrast is too low to find the pattern: grey levels 1..16 of 255 (a range of 15, at least 20" in err


# --- a measurement is checked against the pattern it claims to be (psvs.accuracy.pattern_measure) ---



def test_an_image_of_another_size_is_refused(images):
    """A resized or cropped image moves every pixel's ray (it measured Z = 868 mm at 640 mm, all circles
    10 mm): bad input, like psvs match."""
    import cv2
    img = images[(589, 0)]
    rig = default_rig()
    for small, size in ((cv2.resize(img, (480, 360)), "480x360"), (img[:, :600], "600x480")):
        with pytest.raises(ValueError, match=f"image is {size} px but the rig's camera is 640x480 px"):
            measure_pattern(small, rig)


def test_a_count_other_than_the_images_is_refused(images):
    """--count 3 on the 5-circle pattern measured Z = 1870 mm at 1123 mm: 3 of 10 circles picked. More
    circles than the count is not that pattern; fewer is a circle missing. Both are measurements the image does
    not support (exit 1), as an adversarial trial asked: --count 6 exited 2, --count 3 exited 1."""
    img, rig = images[(1123, 0)], default_rig()
    with pytest.raises(MeasurementError, match=r"found 10 circles, expected 6 \(3 per view\): the image shows "
                                               r"more circles than the pattern's 3"):
        measure_pattern(img, rig, count=3)
    with pytest.raises(MeasurementError, match=r"found 10 circle\(s\), expected 12 \(6 per view\)"):
        measure_pattern(img, rig, count=6)


@pytest.mark.parametrize("shot, used", [("misaligned", "default"), ("default", "misaligned")])
def test_another_builds_image_is_refused(shot, used):
    """The misaligned build's image measured with the ideal rig gave circles of 24-27 mm (and the other way
    round 25-29 mm) at about the right depth: no circle's twin lies within 1 px of its epipolar curve through
    the rig used (the nearest 7-10 px off), so no pairing exists."""
    img = render(builtin_scene("fig9:distance_mm=640"), load_rig(shot), seed=5).image
    with pytest.raises(MeasurementError, match=r"no pairing of the 10 circles puts every twin on its epipolar curve "
                                               r"through this rig within 400-1200 mm: the circle at \(\d+\.\d, "
                                               r"\d+\.\d\) px has no twin: ([789]|10)\.\d\d px from the nearest, "
                                               r"tolerance 1 px"):
        measure_pattern(img, load_rig(used))
    assert abs(measure_pattern(img, load_rig(shot)).diameter_mm - 10.0) < 0.1      # its own rig measures it


def test_diameters_and_spacings_are_checked_against_the_pattern(images):
    """Asked for 12 mm circles or a 25 mm spacing, the paper's pattern is refused with the numbers and the
    tolerance (1 px, 0.57 mm at 589 mm); the diameter check on a measurement of 25 mm circles (another
    build's optics) names it."""
    from psvs.accuracy.pattern_measure import PatternMeasurement, check_geometry, footprint_mm
    img, rig = images[(589, 0)], default_rig()
    px = footprint_mm(rig, 589.0)
    assert px == pytest.approx((589 + 50) * 0.01 / 11.3) and 0.56 < px < 0.57
    with pytest.raises(MeasurementError, match=r"circle \d's diameter is 9\.\d+ mm, the pattern's 12 mm, "
                                               r"tolerance 0\.56\d mm at Z = 589 mm \(1 px of"):
        measure_pattern(img, rig, diameter_mm=12.0)
    with pytest.raises(MeasurementError, match=r"the nearest \(Z = 589 mm\): circles 1 and 5 are (79\.9|80\.0)\d+ mm "
                                               r"apart, the pattern's 100 mm, tolerance 0\.\d+ mm at Z = 589 mm"):
        measure_pattern(img, rig, spacing_mm=25.0)
    centres = np.column_stack([np.arange(5) * 20.0, np.zeros(5), np.full(5, 640.0)])
    wide = PatternMeasurement(640.0, np.array([24.0, 26.0, 23.1, 25.5, 27.3]), 25.2, 80.0, centres)
    with pytest.raises(MeasurementError, match=r"circle 5's diameter is 27\.300 mm, the pattern's 10 mm"):
        check_geometry(wide, rig, 20.0, 10.0)
    check_geometry(PatternMeasurement(640.0, np.full(5, 10.3), 10.3, 80.0, centres), rig, 20.0, 10.0)
    unpaired = PatternMeasurement(640.0, np.array([10.0, np.nan, 10.0, 10.0, 10.0]), 10.0, 80.0, centres)
    with pytest.raises(MeasurementError, match="circle 2's diameter cannot be measured"):
        check_geometry(unpaired, rig, 20.0, 10.0)
    with pytest.raises(ValueError, match=r"diameter_mm \(20 mm\) must be less than spacing_mm \(20 mm\)"):
        measure_pattern(img, rig, diameter_mm=20.0)


def test_another_printed_pattern_measures_with_its_sizes():
    """Four 8 mm circles 15 mm apart (`--count 4 --spacing-mm 15 --diameter-mm 8`) at 700 mm."""
    from dataclasses import replace
    rig = default_rig()
    scene = builtin_scene("fig9:distance_mm=700")
    sheet = scene.objects[0]
    texture = replace(sheet.texture, count=4, diameter_mm=8.0, spacing_mm=15.0)
    img = render(replace(scene, objects=(replace(sheet, texture=texture),)), rig, seed=2).image
    m = measure_pattern(img, rig, count=4, spacing_mm=15.0, diameter_mm=8.0)
    assert abs(m.Z_mm - 700) < 0.5 and np.abs(m.diameters_mm - 8.0).max() < 0.2
    assert abs(m.first_last_distance_mm - 45.0) < 0.2
    with pytest.raises(MeasurementError, match="the pattern's 10 mm"):
        measure_pattern(img, rig, count=4, spacing_mm=15.0)


@pytest.mark.slow
@pytest.mark.parametrize("rig_name", ["default", "misaligned"])
def test_good_images_at_every_table1_distance_still_measure(rig_name):
    """The paper's 15 distances, on the robot's holder (psvs table1's images) and flat (`fig9:distance_mm=`),
    measured with the rig they were taken through: every check passes and the accuracy is what it was
    (|Z error| <= 0.6 mm, diameters within 0.1 mm on average, first-last distance within 0.25 mm)."""
    from psvs.accuracy.table1 import PAPER_TABLE1, pattern_image
    rig = load_rig(rig_name)
    for z in PAPER_TABLE1[:, 0]:
        for img in (pattern_image(rig, z, int(z) + 1), render(builtin_scene(f"fig9:distance_mm={z}"), rig,
                                                                 seed=int(z)).image):
            m = measure_pattern(img, rig)
            assert abs(m.Z_mm - z) <= 0.6 and abs(m.diameter_mm - 10.0) <= 0.1, (z, m.to_dict())
            assert abs(m.first_last_distance_mm - 80.0) <= 0.25, (z, m.to_dict())


def test_circles_stretched_along_one_axis_are_not_round():
    """A pixel pitch 10 % off along the rows (the image made through a rig whose pixels are 9.09 um wide,
    measured with the 10 um one) or an image stretched 10 % along either axis: the circles' mean diameters can
    pass (the first read Z 577 mm for 640, every other check passing), but every circle is wider than tall (or
    taller than wide) alike; refused, saying which and by how much. The unstretched image stays round."""
    from dataclasses import replace

    import cv2

    from psvs.errors import MeasurementError
    rig = default_rig()
    scene = builtin_scene("fig9:distance_mm=640")
    narrow = replace(rig, camera=replace(rig.camera, pixel_pitch_mm=(0.00909, 0.01)))
    img = render(scene, rig, seed=3).image
    assert measure_pattern(img, rig).Z_mm == pytest.approx(640.0, abs=0.5)
    cases = [(render(scene, narrow, seed=3).image, "wider than tall")]
    for m, says in (([[1.1, 0, -32], [0, 1, 0]], "wider than tall"), ([[1, 0, 0], [0, 1.1, -24]], "taller than wide")):
        cases.append((cv2.warpAffine(img, np.float32(m), (640, 480)), says))
    for s, says in cases:
        with pytest.raises(MeasurementError, match=rf"the circles are not round: 5 of them are {says} by 0\.\d+ mm "
                                                   r"on average, tolerance 0\.\d+ mm at Z = \d+ mm"):
            measure_pattern(s, rig)


def test_every_table1_distance_is_round(images):
    """The rendered Table I distances (flat and tilted by 10 and 15 deg) are round within 0.75 of the
    tolerance (docs: 0.71 at most over both builds and both 1440 x 1080 rigs, the tilted ones the largest)."""
    from psvs.accuracy.pattern_measure import roundness_problem
    rig = default_rig()
    for c, img in images.items():
        m = measure_pattern(img, rig)
        ratio, why = roundness_problem(m.stretch_mm, m.Z_mm, rig)
        assert ratio <= 0.75 and why == "", (c, ratio)


def test_a_pattern_outside_the_range_is_named_as_such():
    """An adversarial trial: Fig. 9 at 300 mm measured over 1000-2000 mm said only that circles were missing or
    out of view; the circles' sizes looked for come from the range, and the refusal now says so."""
    rig = default_rig()
    img = render(builtin_scene("fig9:distance_mm=300"), rig, seed=3).image
    with pytest.raises(MeasurementError, match=r"or the pattern stands outside the working range 1000-2000 mm \(its "
                                         r"circles looked for \d+-\d+ px across\)"):
        measure_pattern(img, rig, z_mm=(1000.0, 2000.0))
    assert abs(measure_pattern(img, rig, z_mm=(250.0, 1200.0)).Z_mm - 300.0) <= 0.6    # a range that holds it


def test_a_pattern_nearer_than_the_range_whose_circles_pair_wrongly_names_the_range():
    """An adversarial trial: Fig. 9 at 350 mm over the default 400-1200 mm is found whole (its circles fall within
    the sizes looked for) but its twins pair only wrongly (the nearest way at Z = 789 mm): refused on the spacing,
    the refusal now also names the working range; over 300-1200 mm it measures."""
    rig = default_rig()
    img = render(builtin_scene("fig9:distance_mm=350"), rig, seed=4).image
    with pytest.raises(MeasurementError, match=r"fits the pattern; .*; or the pattern lies outside the working "
                                               r"range 400-1200 mm: give --near-mm/--far-mm that hold it$"):
        measure_pattern(img, rig)
    assert abs(measure_pattern(img, rig, z_mm=(300.0, 1200.0)).Z_mm - 350.0) <= 0.6
