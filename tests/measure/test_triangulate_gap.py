"""The epipolar gap of matched pixels (psvs.measure.triangulate.epipolar_gap_px) against planted twins:
zero for true twins, and for a right pixel moved off its row by dv the gap the geometry gives (the moved
pixel's ray passes the point at dv pixel footprints: dv px, to first order)."""
import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.measure.triangulate import epipolar_gap_px
from psvs.optics.project import project_points


@pytest.mark.parametrize("name", ["default", "misaligned", "mv1440_misaligned"])
def test_twins_have_no_gap_and_a_moved_pixel_its_offset(name):
    rig = load_rig(name)
    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(-60, 60, 40), rng.uniform(-40, 40, 40), rng.uniform(450, 1150, 40)])
    left, okl = project_points(pts, rig, "left")
    right, okr = project_points(pts, rig, "right")
    ok = okl & okr
    left, right = left[ok], right[ok]
    assert len(left) > 20
    assert np.nanmax(epipolar_gap_px(left, right, rig)) < 0.01
    for dv in (3.0, 10.0):
        moved = right + [0.0, dv]
        gap = epipolar_gap_px(left, moved, rig)
        np.testing.assert_allclose(gap, dv, rtol=0.1)
