"""Pairing the two views' circles by the rig's geometry (psvs.targets.pattern) on any camera: the paper's
640x480 rig and the 1440x1080 machine-vision rigs (mv1440, mv1440_misaligned), patterns side by side,
interleaved and overlapping, tilted and off-centre; images that are not the pattern exit 1 with no numbers."""
import json
from dataclasses import dataclass, replace

import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.accuracy.pattern_measure import measure_pattern
from psvs.errors import MeasurementError
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from psvs.simulate.textures import Circles
from psvs.targets.discs import split_two_discs
from psvs.targets.pattern import detect_circles, disc_size_range_px, lens_scale_range, perfect_matchings
from tests.support.cli import run


def pattern_scene(z, tilt_x=0.0, tilt_y=0.0, x=0.0, y=0.0, **texture):
    """Fig. 9's sheet at depth z (mm), turned and moved, its row of circles changed by ``texture``
    (count, spacing_mm, diameter_mm), the sheet 20 mm longer than the row on each side."""
    scene = builtin_scene(f"fig9:distance_mm={z},tilt_x_deg={tilt_x},tilt_y_deg={tilt_y},x_mm={x},y_mm={y}")
    sheet = scene.objects[0]
    tex = replace(sheet.texture, **texture)
    width = max(120.0, (tex.count - 1) * tex.spacing_mm + tex.diameter_mm + 40.0)
    return replace(scene, objects=(replace(sheet, texture=tex, size_mm=(width, 50.0)),))


@dataclass(frozen=True)
class OneCircleLarger(Circles):
    """Fig. 9's row with circle ``which`` (0-based) ``larger_mm`` wider than the others."""

    which: int = 2
    larger_mm: float = 3.0

    def __call__(self, xy_mm):
        out = super().__call__(xy_mm)
        cx, cy = self.centres_mm()[self.which]
        r = (self.diameter_mm + self.larger_mm) / 2
        return np.where((xy_mm[:, 0] - cx) ** 2 + (xy_mm[:, 1] - cy) ** 2 <= r * r, self.low, out)


def test_perfect_matchings_by_hand():
    """Four circles 0-3 (u increasing), candidate twins (left, right) 1->0, 3->2, 2->0, 3->1, 2->1: the
    assignments using every circle once are {1->0, 3->2} and {2->0, 3->1}; {2->1} leaves 0 and 3, and 3->0
    is no candidate. An odd number of circles has none."""
    edges = np.zeros((4, 4), bool)
    for a, b in ((1, 0), (3, 2), (2, 0), (3, 1), (2, 1)):
        edges[a, b] = True
    assert sorted(perfect_matchings(edges)) == [[(1, 0), (3, 2)], [(2, 0), (3, 1)]]
    assert perfect_matchings(np.ones((3, 3), bool)) == []
    with pytest.raises(MeasurementError, match="pair in more than 3 ways"):
        perfect_matchings(~np.eye(6, dtype=bool), limit=3)


def test_detector_sizes_come_from_the_rig_and_the_working_range():
    """By hand. Paper's rig (no distortion): a 10 mm disc at 400 mm is 10 x 11.3 / (0.01 x 450) = 25.1 px,
    x 1.25 = 31.4 -> 32 px; at 1200 mm 9.04 px, a quarter of its area 16.0 px^2. mv1440 (8 mm, 3.45 um):
    51.5 px at 400 mm, x 1.25 -> 65 px (the lens's scale is 1 at the centre), far above the old fixed 40 px;
    its barrel lens (k1 = -0.27) shrinks the field's edge (scale < 1, > 0.7)."""
    area, widest = disc_size_range_px(default_rig(), 10.0, 400.0, 1200.0)
    assert widest == 32 and area == pytest.approx(np.pi / 4 * (10 * 11.3 / 12.5) ** 2 * 0.25, rel=1e-9)
    mv = load_rig("mv1440")
    lo, hi = lens_scale_range(mv)
    assert 0.7 < lo < 0.95 and hi == pytest.approx(1.0, abs=1e-3)
    assert disc_size_range_px(mv, 10.0, 400.0, 1200.0)[1] == 65
    assert disc_size_range_px(mv, 10.0, 800.0, 1200.0)[1] < 40            # a farther range, smaller discs


@pytest.mark.parametrize("d_over_r", [0.6, 1.0, 1.6])
def test_two_overlapping_discs_split_from_their_outline(d_over_r):
    """The outline of two overlapping circles (radii 20 and 18 px, centres d apart) gives both back within
    0.05 px (exact outline points, no pixels)."""
    c1, c2, r1, r2 = np.array([100.0, 50.0]), np.array([100.0 + d_over_r * 20, 53.0]), 20.0, 18.0
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    p1 = c1 + r1 * np.column_stack([np.cos(t), np.sin(t)])
    p2 = c2 + r2 * np.column_stack([np.cos(t), np.sin(t)])
    outline = np.vstack([p1[np.linalg.norm(p1 - c2, axis=1) > r2], p2[np.linalg.norm(p2 - c1, axis=1) > r1]])
    (a, ra), (b, rb) = sorted(split_two_discs(outline), key=lambda s: s[0][0])
    assert np.abs(a - c1).max() < 0.05 and np.abs(b - c2).max() < 0.05
    assert abs(ra - r1) < 0.05 and abs(rb - r2) < 0.05


POSES = [  # (rig, z, tilt_x, tilt_y, x, y): near (discs up to 47 px), tilted both ways, off-centre
    ("mv1440", 440, 0, 0, 0, 0), ("mv1440", 600, 0, 35, -40, 10), ("mv1440", 1000, 3, -20, 30, -10),
    ("mv1440", 1150, 4, -10, 50, -15), ("mv1440_misaligned", 489, 2, -3, 6, -4),
    ("mv1440_misaligned", 760, 0, 20, 20, 0), ("mv1440_misaligned", 880, -5, 10, -30, 10),
    ("default", 440, 20, -10, 30, 0)]


@pytest.mark.slow  # renders through the 1440x1080 rigs (the first of each rig ~1 min)
@pytest.mark.parametrize("rig_name, z, tx, ty, x, y", POSES)
def test_planted_poses_measure(rig_name, z, tx, ty, x, y):
    """The pattern turned and moved, through each rig, measured with that rig: |Z error| <= 0.3 mm, every
    diameter within 0.3 mm, the first-last distance within 0.2 mm. mv1440_misaligned's views are turned
    against each other: from 489 mm on a circle of one view overlaps one of the other (split in two).
    Known limit: tilted 20-25 deg far out (1150 mm on mv1440, 880 mm on the build), where the other view's
    sheet border or circle runs along a rim, a diameter is 0.4-0.7 mm off and the image is refused."""
    rig = load_rig(rig_name)
    m = measure_pattern(render(pattern_scene(z, tx, ty, x, y), rig, seed=z).image, rig)
    assert abs(m.Z_mm - z) <= 0.3 and np.abs(m.diameters_mm - 10.0).max() <= 0.3, m.to_dict()
    assert abs(m.first_last_distance_mm - 80.0) <= 0.2, m.to_dict()


@pytest.mark.slow  # renders through the 1440x1080 rigs (the first of each rig ~1 min)
@pytest.mark.parametrize("rig_name, z, ty", [("default", 520, 10), ("mv1440", 450, 0), ("mv1440", 1000, -15)])
def test_interleaved_views_pair(rig_name, z, ty):
    """Four circles 40 mm apart (a 130 mm row, wider than the 100 mm baseline): the two views' circles
    alternate along the image row (sorting by u cannot split them); paired by the rig's geometry they
    measure |Z error| <= 0.3 mm, diameters within 0.4 mm (0.15 mm on average; the other view's sheet edge
    runs beside every circle), 120 mm first to last within 0.3 mm."""
    rig = load_rig(rig_name)
    img = render(pattern_scene(z, 0, ty, count=4, spacing_mm=40.0), rig, seed=z).image
    m = measure_pattern(img, rig, count=4, spacing_mm=40.0)
    assert abs(m.Z_mm - z) <= 0.3 and np.abs(m.diameters_mm - 10.0).max() <= 0.4, m.to_dict()
    assert abs(m.diameter_mm - 10.0) <= 0.15, m.to_dict()
    assert abs(m.first_last_distance_mm - 120.0) <= 0.3, m.to_dict()


@pytest.fixture(scope="module")
def mv_700():
    return render(pattern_scene(700.0), load_rig("mv1440"), seed=7).image


def _cannot(capsys, tmp_path, image, pattern, *args):
    path = tmp_path / "planted.png"
    write_png(path, image)
    code, out, err = run(capsys, "measure", "circles", str(path), "--rig", "mv1440", *args)
    assert code == 1 and out == "" and err.count("\n") == 1 and "cannot measure" in err, (code, out, err)
    assert pattern in err, err


def test_planted_inconsistent_images_exit_1_with_no_numbers(capsys, tmp_path, mv_700):
    """mv1440 at 700 mm: the good image measures; one circle 3 mm wider, a circle painted out of one view,
    a row printed 22 mm apart (asked for 20), and the right spacing with the wrong count of circles: exit 1,
    one line, nothing on stdout."""
    rig = load_rig("mv1440")
    path = tmp_path / "good.png"
    write_png(path, mv_700)
    code, out, _ = run(capsys, "measure", "circles", str(path), "--rig", "mv1440", "--json")
    assert code == 0 and abs(json.loads(out)["Z_mm"] - 700.0) < 0.3
    larger = replace(pattern_scene(700.0), objects=(replace(pattern_scene(700.0).objects[0],
                                                             texture=OneCircleLarger()),))
    _cannot(capsys, tmp_path, render(larger, rig, seed=7).image, "circle 3's diameter is 1")
    painted = mv_700.copy()
    first = min(detect_circles(mv_700, 5, max_diameter_px=65), key=lambda e: e.centre_px[0])   # right view's
    mask = np.zeros_like(painted)
    cv2.circle(mask, tuple(int(round(c)) for c in first.centre_px), int(first.axes_px[0] + 8), 255, -1)
    painted = cv2.inpaint(painted, mask, 5, cv2.INPAINT_TELEA)
    _cannot(capsys, tmp_path, painted, "found 9 circles, expected 10 (5 per view): one view shows a circle")
    wide = render(pattern_scene(700.0, spacing_mm=22.0), rig, seed=7).image
    _cannot(capsys, tmp_path, wide, "circles 1 and 5 are 88.0")
    _cannot(capsys, tmp_path, mv_700, "found 10 circles, expected 8", "--count", "4")


def test_the_working_range_bounds_the_twins(capsys, tmp_path, mv_700):
    """The same 700 mm image with --near-mm 800: no twin has its disparity in 800-1200 mm, exit 1."""
    _cannot(capsys, tmp_path, mv_700, "within 800-1200 mm", "--near-mm", "800")


def _table1_acceptance(rows):
    """rows (15, 4): Z meas., Z calc., d calc., a calc. (mm). Every distance measured; mean |Z error| after
    the common offset (frame C's depth origin, which no image fixes: docs/calibration.md) <= 0.1 mm;
    diameters within 0.03 mm on average; the first-last distance within 0.1 mm on average."""
    from psvs.accuracy.table1 import PAPER_TABLE1
    assert rows.shape == (15, 4) and np.all(np.isfinite(rows))
    assert rows[:, 0] == pytest.approx(PAPER_TABLE1[:, 0])
    z_err = rows[:, 1] - rows[:, 0]
    assert np.abs(z_err - z_err.mean()).mean() <= 0.1, z_err
    assert np.abs(rows[:, 2] - 10.0).mean() <= 0.03 and np.abs(rows[:, 3] - 80.0).mean() <= 0.1, rows


@pytest.mark.slow
def test_table1_cli_on_mv1440(capsys, tmp_path):
    """`psvs table1 --rig mv1440` end to end (sweep from the rough start, the 15 distances): table1.csv meets
    the acceptance (measured: 0.024 mm mean |Z error| after a 0.12 mm offset, diameters 0.006 mm)."""
    import csv
    code, out, err = run(capsys, "table1", "--rig", "mv1440", "-o", str(tmp_path))
    assert code == 0, err
    rows = list(csv.DictReader((tmp_path / "table1.csv").open()))
    _table1_acceptance(np.array([[float(r[k]) for k in ("Z_meas_mm", "Z_calc_mm", "d_calc_mm", "a_calc_mm")]
                                 for r in rows]))


@pytest.mark.slow
def test_table1_on_mv1440_misaligned():
    """The build (mirrors off, the box turned: its views' circles overlap from ~490 mm on), calibrated from
    the sweep alone starting from its design (mv1440, as the paper's build from clear.toml in
    test_table1.py; from the rough guess, no lens and f +10 %, the adjustment stops at 8.8 px RMS), meets
    the acceptance."""
    from psvs.accuracy.table1 import run_table1
    design = load_rig("mv1440").with_extents({k: None for k in ("m1", "m2", "m3", "m4")})
    t = run_table1(load_rig("mv1440_misaligned"), start=design)
    assert t.calibration.rms_px < 0.1
    _table1_acceptance(t.rows())


@pytest.mark.slow  # renders through the 1440x1080 rigs (the first of each rig ~1 min)
def test_two_consistent_pairings_are_refused_not_picked():
    """mv1440_misaligned at 925 mm on the robot's holder: a circle of each view overlaps one of the other
    (12 px apart). Before calibration (its design as the start rig: twins within 2 deg of view turn, a row
    of equal gaps) swapping those two circles' views also fits: 2 assignments, refused. The build's own
    rig (1 px, the printed spacing and diameters) leaves one, 925 mm within 0.3 mm."""
    from psvs.accuracy.table1 import pattern_image
    from psvs.targets.pattern import detect_with_start
    build = load_rig("mv1440_misaligned")
    design = load_rig("mv1440").with_extents({k: None for k in ("m1", "m2", "m3", "m4")})
    img = pattern_image(build, 925.0, 925)
    with pytest.raises(MeasurementError, match=r"^2 of the \d+ ways to pair the 10 circles on their epipolar curves "
                                               r"through the start rig form a row of 5 circles 20 mm apart"):
        detect_with_start(img, design)
    assert abs(measure_pattern(img, build).Z_mm - 925.0) <= 0.3
