"""Tolerance analysis against closed forms of small mirror and camera errors."""
import json
import math

import pytest

from psvs import default_rig
from psvs.measure.tolerance import TILT_STEP_RAD, field_points, tolerance_analysis
from psvs.optics.search_range import disparity_range
from tests.support.cli import run


@pytest.fixture(scope="module")
def rows():
    return {(r.part, r.component.split(" (")[0]): r for r in tolerance_analysis(default_rig())}


def test_every_mirror_error_and_the_box_are_listed(rows):
    assert len(rows) == 4 * 3 + 3
    assert all(r.row_px_max >= r.row_px_mean >= 0 and r.depth_mm_max >= r.depth_mm_mean >= 0 for r in rows.values())


@pytest.mark.parametrize("mirror", ["M1", "M2", "M3", "M4"])
def test_tilt_out_of_vertical_deflects_rows_by_root2_delta(rows, mirror):
    """A 45 deg mirror turned by delta about its in-plane horizontal axis: the normal gains -delta along Y,
    the reflected ray turns by 2 (d.n) delta = sqrt(2) delta vertically -> sqrt(2) delta f / pitch rows."""
    rig = default_rig()
    expected = math.sqrt(2) * TILT_STEP_RAD * rig.camera.focal_length_mm / rig.camera.pixel_pitch_mm[1]
    assert rows[(mirror, "tilt b")].row_px_mean == pytest.approx(expected, rel=0.1)   # 2.79 px


@pytest.mark.parametrize("mirror", ["M3", "M4"])
def test_shift_of_an_outer_mirror_changes_the_baseline(rows, mirror):
    """M3 (or M4) moved s along its 45 deg normal moves its virtual camera 2 s along it: the baseline
    changes by sqrt(2) s, and Z (proportional to b) by Z sqrt(2) s / b (plus < 0.1 mm from the depth step)."""
    rig = default_rig()
    z_mean = field_points(rig, 400.0, 1200.0)[:, 2].mean()
    expected = z_mean * math.sqrt(2) * 0.1 / rig.mirrors.baseline_mm
    assert rows[(mirror, "shift")].depth_mm_mean == pytest.approx(expected, abs=0.1 + 0.05 * expected)


def test_camera_turned_in_its_mount(rows):
    """About the optical axis (Z) by theta, the twins d px apart move theta * d rows apart (d up to the
    working range's largest disparity); about X both views move alike: no row disagreement."""
    d_max = disparity_range(default_rig(), 400.0, 1200.0)[1]
    assert rows[("mirror box", "turned about Z")].row_px_max == pytest.approx(TILT_STEP_RAD * d_max, rel=0.05)
    assert rows[("mirror box", "turned about X")].row_px_max < 0.02


def test_effects_grow_linearly():
    small = tolerance_analysis(default_rig(), tilt_step_rad=math.radians(0.05), shift_step_mm=0.05)
    big = tolerance_analysis(default_rig())
    for s, b in zip(small, big, strict=True):
        assert b.row_px_mean == pytest.approx(2 * s.row_px_mean, rel=0.05, abs=1e-3)
        assert b.per_px == pytest.approx(s.per_px, rel=0.05) or b.row_px_max < 0.02


def test_bad_range():
    with pytest.raises(ValueError, match="working range"):
        tolerance_analysis(default_rig(), 500.0, 400.0)


def test_design_tolerance_cli_table_and_file(capsys, tmp_path, rows):
    out = tmp_path / "design.json"
    code, text, err = run(capsys, "design", "--rig", "default", "--tolerance", "-o", str(out))
    assert code == 0, err
    assert "Tolerance: each error alone" in text and "1 px of rows" in text
    tol = json.loads(out.read_text())["tolerance"]
    assert len(tol) == 15
    by = {(t["part"], t["error"].split(" (")[0]): t for t in tol}
    r = rows[("M2", "tilt b")]
    t = by[("M2", "tilt b")]
    assert t["step_deg"] == pytest.approx(0.1) and t["rows_apart_px_mean"] == pytest.approx(r.row_px_mean)
    assert t["error_for_1px_deg"] == pytest.approx(math.degrees(r.per_px))
    assert by[("M3", "shift")]["depth_error_mm_mean"] == pytest.approx(rows[("M3", "shift")].depth_mm_mean)
    line = next(ln for ln in text.splitlines() if ln.startswith("M2") and "tilt b" in ln)
    assert f"{r.row_px_max:.2f}" in line and f"{math.degrees(r.per_px):.3f} deg" in line
