"""The row offset the paper's geometry makes itself (psvs.health.plate_shift): the M1 plate's shift of the left
view's rows, predicted from the left ray and the disparity alone, against both views' exact projections of
drawn points on drawn ideal rigs; and the check that judges what is left: a strict tolerance on the ideal rig
(docs/health.md: walls at 400-550 mm read "drifted 0.21-0.30 px" with --tolerance-px 0.15, nothing moved)."""
import dataclasses

import numpy as np
import pytest

from psvs.health.check import check_frames, judge, judged_pairs_px
from psvs.health.plate_shift import rig_row_offsets
from psvs.health.rows import frame_tiles
from psvs.io.params import load_rig
from psvs.optics.project import in_image, project_points
from psvs.optics.rig import default_rig
from psvs.simulate.render import render
from tests.support.drift import wall


@pytest.mark.parametrize("seed", range(4))
def test_the_predicted_row_shift_is_the_optics_on_drawn_rigs(seed):
    """Ideal rigs drawn over baselines 60-160 mm, plates 1-3 mm, lenses 8-16 mm: for points over the field at
    350-1500 mm, the right view's row minus the left's from the left pixel and the disparity alone equals both
    views' exact projections' within 1e-4 px; a disparity no point of the ray shows (negative) gives NaN."""
    rng = np.random.default_rng(seed)
    rig = default_rig().replace(baseline_mm=float(rng.uniform(60, 160)), plate_thickness_mm=float(rng.uniform(1, 3)),
                                focal_length_mm=float(rng.uniform(8, 16)))
    pts = np.column_stack([rng.uniform(-150, 150, 300), rng.uniform(-100, 100, 300), rng.uniform(350, 1500, 300)])
    left, okl = project_points(pts, rig, "left")
    right, okr = project_points(pts, rig, "right")
    ok = okl & okr & in_image(left, rig) & in_image(right, rig)
    assert ok.sum() > 50
    got = rig_row_offsets(rig, left[ok], left[ok, 0] - right[ok, 0])
    np.testing.assert_allclose(got, right[ok, 1] - left[ok, 1], atol=1e-4)
    assert np.abs(right[ok, 1] - left[ok, 1]).max() > 0.05        # the plate does shift them
    assert np.isnan(rig_row_offsets(rig, left[ok][:1], [-30.0]))[0]


def test_a_strict_tolerance_holds_on_the_ideal_rig():
    """A wall at 420 mm through the default rig, nothing moved, checked at 0.15 px: the raw rows read a field of
    0.2-0.4 px (the plate's shift: a "drifted" verdict before); less what the rig makes, healthy, the field
    within 0.1 px of none. The judged pairs are the measured ones (a refit reads them), the shift added back."""
    rig = load_rig("default")
    img = render(wall(420.0, 3), rig, seed=3).image
    tiles = frame_tiles(img, rig)
    raw = judge([dataclasses.replace(tiles, expected_px=None)], 0.15)
    assert raw.verdict == "drifted" and 0.2 <= raw.row_offset_rms_px <= 0.4
    check = check_frames([img], rig, tolerance_px=0.15)
    assert check.verdict == "healthy" and check.row_offset_rms_px <= 0.1, check.reason
    left, right = judged_pairs_px(check, rig)
    k = np.flatnonzero(tiles.accepted)
    measured = {tuple(np.round(c, 6)): o for c, o in zip(tiles.centre_px[k], tiles.offset_px[k], strict=True)}
    for lp, rp in zip(left, right, strict=True):
        assert rp[1] - lp[1] == pytest.approx(measured[tuple(np.round(lp, 6))], abs=1e-9)


def test_a_build_makes_no_offset_of_its_own():
    """On a build the rectified grids account for the plate: nothing is predicted, nothing subtracted."""
    rig = load_rig("misaligned")
    tiles = frame_tiles(render(wall(700.0, 4), rig, seed=4).image, rig)
    assert tiles.expected_px is None and tiles.accepted.sum() > 20
