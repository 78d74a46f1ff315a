"""The paper's accuracy pattern (Fig. 9) in rendered complex images, measured with the known rig
(nothing calibrated: these are the measurement's own errors)."""
import json

import numpy as np
import pytest

from psvs import default_rig
from psvs.calibrate.measure import measure_pattern
from psvs.calibrate.targets import detect_pattern
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from tests.cli.test_cli import EXAMPLE, run

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
    with pytest.raises(ValueError, match=r"found 3 circle\(s\), expected 10 \(5 per view\)"):
        measure_pattern(off, rig)
    # one circle missing: a sheet with four circles
    from dataclasses import replace
    scene = builtin_scene("fig9:distance_mm=700")
    sheet = scene.objects[0]
    four = replace(scene, objects=(replace(sheet, texture=replace(sheet.texture, count=4)),))
    with pytest.raises(ValueError, match=r"found 8 circle\(s\), expected 10"):
        measure_pattern(render(four, rig, seed=1).image, rig)


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
