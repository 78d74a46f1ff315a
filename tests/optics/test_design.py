import math
import re
from pathlib import Path

import numpy as np
import pytest

from psvs import default_rig
from psvs.errors import RigGeometryError
from psvs.optics.design import design_mirrors, working_range
from psvs.optics.layout_check import check_clear
from psvs.optics.mirror_length import mirror_length_eq6
from psvs.optics.rig import MIRROR_NAMES
from psvs.optics.trace import trace_pixels


def all_pixels(rig, step=4):
    """Every 4th pixel plus the outer pixel edges (the field's boundary rays)."""
    w, h = rig.camera.image_size_px
    u, v = np.meshgrid(np.r_[-0.5, np.arange(0, w, step), w - 0.5], np.r_[-0.5, np.arange(0, h, step), h - 0.5])
    return np.column_stack([u.ravel(), v.ravel()])


def test_every_field_ray_lands_on_its_mirror(clear_rig):
    px = all_pixels(clear_rig)
    for view in ("left", "right"):
        assert trace_pixels(px, clear_rig, view).valid.all()


@pytest.mark.parametrize("name", MIRROR_NAMES)
def test_shrinking_a_mirror_by_2_percent_vignettes(clear_rig, name):
    shrunk = clear_rig.with_extents({name: clear_rig.mirrors.extent(name).scaled(0.98)})
    px = all_pixels(clear_rig)
    lost = sum((~trace_pixels(px, shrunk, view).valid).sum() for view in ("left", "right"))
    assert lost > 0


def test_clear_layout_has_no_obstruction(clear_rig):
    d = design_mirrors(clear_rig, search=False)
    assert d.ok and d.problems == []


def test_default_layout_is_clear():
    """The project's default rig (c1 = 22, c2 = 44 mm) clears both light paths (c1 = 25, c2 = 45 mm does
    not: the next test)."""
    d = design_mirrors(default_rig())
    assert d.ok and d.problems == []
    lo, hi = d.m2_window_mm
    assert lo < 44.0 < hi


def test_the_readmes_mirror_sizes_are_the_designs():
    """The README's row of mirror sizes (width x height and eq. (6), mm) is what the design gives the default
    rig, to its printed digits (it once gave another layout's sizes), and its layout is the default's."""
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    row = next(line for line in readme.splitlines() if line.startswith("| mirror sizes for the default rig"))
    printed = {m[0]: tuple(map(float, m[1:])) for m in
               re.findall(r"M(\d) ([\d.]+) × ([\d.]+) mm \((?:eq\. 6: )?([\d.]+)\)", row)}
    assert sorted(printed) == ["1", "2", "3", "4"], row
    rig = default_rig()
    assert f"c1 = {rig.mirrors.m1_axis_distance_mm:g}, c2 = {rig.mirrors.m2_axis_distance_mm:g} mm" in row
    for spec in design_mirrors(rig, search=False).mirrors:
        (t0, t1) = spec.extent.height_mm
        want = (spec.extent.width_mm, t1 - t0, spec.eq6_length_mm)
        assert printed[spec.name[1]] == pytest.approx(want, abs=0.005), spec.name


def test_blocked_layout_names_the_mirror():
    """c1 = 25, c2 = 45 with a 3 mm plate: the plate's far end crosses M2's plane (see docs/optics.md)."""
    d = design_mirrors(default_rig().replace(m1_axis_distance_mm=25.0, m2_axis_distance_mm=45.0))
    assert not d.ok
    assert "M2 cuts through the M1 plate" in d.problems
    assert any(p.startswith("M2 blocks the left view between M1 plate -> M2") for p in d.problems)
    assert d.m2_window_mm is None
    c1, c2 = d.suggestion_mm
    assert c1 < 25.0
    fixed = design_mirrors(default_rig().replace(m1_axis_distance_mm=c1, m2_axis_distance_mm=c2), search=False)
    assert fixed.ok


@pytest.mark.parametrize("plate_mm", [0.0, 3.0])
def test_far_m2_blocks_outgoing_left_beam(plate_mm):
    """By hand (45 deg, no plate): the left view's edge ray (the image's last column, u = W - 0.5) clears M2's
    far end only while c2 < b (1 - tan a)^2 / (4 tan a) ~ 45.4 mm. Without the plate the layout is clear
    0.3 mm below that bound and blocked by that beam 0.3 mm above it, and at c2 = 60 mm M2 is in the way
    with or without the plate, the example pixel on the last column."""
    rig = default_rig().replace(plate_thickness_mm=plate_mm, m1_axis_distance_mm=20.0)
    w = rig.camera.image_size_px[0]
    bound = 100.0 * (1 - math.tan(rig.camera.half_fov_rad[0])) ** 2 / (4 * math.tan(rig.camera.half_fov_rad[0]))
    beam = "M2 blocks the left view between M3 -> scene"
    if plate_mm == 0.0:
        assert design_mirrors(rig.replace(m2_axis_distance_mm=bound - 0.3), search=False).ok
        above = design_mirrors(rig.replace(m2_axis_distance_mm=bound + 0.3), search=False).problems
        assert len(above) == 1 and above[0].startswith(beam)
    d = design_mirrors(rig.replace(m2_axis_distance_mm=60.0), search=False)
    (problem,) = [p for p in d.problems if p.startswith(beam)]
    u = float(problem.split("pixel (")[1].split(",")[0])
    assert u == w - 0.5


def test_m2_window_upper_end_matches_closed_form():
    rig = default_rig().replace(plate_thickness_mm=0.0, m1_axis_distance_mm=15.0, m2_axis_distance_mm=35.0)
    tan_a = math.tan(rig.camera.half_fov_rad[0])
    bound = 100.0 * (1 - tan_a) ** 2 / (4 * tan_a)
    lo, hi = design_mirrors(rig).m2_window_mm
    assert hi == pytest.approx(bound, abs=0.02)
    assert lo < 35.0


def test_mirror_widths_follow_eq6():
    """Pure-mirror footprints on planes tilted about Y: their length along the mirror is eq. (6) exactly."""
    rig = default_rig().replace(plate_thickness_mm=0.0)
    d = design_mirrors(rig, search=False)
    a = rig.camera.half_fov_rad[0]
    for spec in d.mirrors:
        assert spec.extent.width_mm == pytest.approx(float(mirror_length_eq6(spec.axis_distance_mm, a, math.pi / 4)),
                                                     abs=1e-9)
    assert [s.axis_distance_mm for s in d.mirrors] == pytest.approx([22.0, 44.0, 94.0, 72.0])


def test_plate_makes_m1_longer_than_eq6(rig):
    spec = design_mirrors(rig, search=False).mirrors[0]
    assert spec.extent.width_mm > spec.eq6_length_mm + 1.0   # the refracted beam leaves the back face further on


def test_heights_cover_vertical_field():
    """M4 height by hand: the corner ray from the virtual centre O' = (-c1, 0, c1) reaches M4 at its far end."""
    rig = default_rig().replace(plate_thickness_mm=0.0)
    d = design_mirrors(rig, search=False)
    tan_x, tan_y = (math.tan(v) for v in rig.camera.half_fov_rad)
    # camera ray (tan_x, tan_y, 1) t hits M1 (z = x + 22) at t1 = 22 / (1 - tan_x); its height grows along the
    # reflected path to M4 (total path OB = 72 along the axis): the far-end height is tan_y * t4 with
    # t4 = 72 / (1 - tan_x) by similar triangles on the unfolded ray.
    assert d.mirrors[3].extent.height_mm[1] == pytest.approx(tan_y * 72.0 / (1 - tan_x), abs=1e-9)


def test_working_range_by_hand(rig):
    wr = working_range(rig, 400.0, 1200.0)
    assert wr.disparity_px == pytest.approx((100 * 11.3 / 1250 / 0.01, 100 * 11.3 / 450 / 0.01))
    assert wr.depth_per_px_mm == pytest.approx((450**2 * 0.01 / 1130, 1250**2 * 0.01 / 1130))
    assert wr.overlap_start_mm == pytest.approx(-50 + 50 / (320 * 0.01 / 11.3))
    with pytest.raises(ValueError, match="0 < near < far"):
        working_range(rig, 500.0, 400.0)


def test_margin_and_impossible_layouts(rig):
    with pytest.raises(ValueError, match="margin_mm must be >= 0"):
        design_mirrors(rig, margin_mm=-1.0)
    wide = rig.replace(focal_length_mm=2.0)  # half field 58 deg > omega_1: the field misses the mirrors
    with pytest.raises(RigGeometryError, match="never reaches"):
        design_mirrors(wide, search=False)


@pytest.mark.parametrize("name", ["default", "clear", "misaligned", "mv1440", "mv1440_misaligned"])
def test_the_shipped_rigs_and_builds_are_clear(name):
    from psvs.io.params import load_rig
    rig = load_rig(name)
    assert check_clear(rig, name) is rig


def test_a_blocked_layout_is_refused_naming_its_first_problem():
    """Issue 41: triangulate and export-calibration went through a rig `psvs design` calls BLOCKED (a 5 mm
    baseline behind a 30 mm plate): check_clear, which every measuring command asks, names the problem."""
    rig = default_rig().replace(baseline_mm=5.0, plate_thickness_mm=30.0)
    d = design_mirrors(rig, search=False)
    assert not d.ok
    with pytest.raises(RigGeometryError, match=rf"^rig x is no layout a build can have: {re.escape(d.share_words())} "
                                               rf"\(more than 50 % is no build\): {re.escape(d.problems[0])} "
                                               rf"\(and {len(d.problems) - 1} more\); `psvs design` shows its layout$"):
        check_clear(rig, "rig x")
