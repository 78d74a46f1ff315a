"""The disparities a working range gives over the field, traced exactly (psvs.optics.search_range.
working_disparities): what dense trust holds answers to (an adversarial trial, 2026-12-06: a search over
1300-2500 mm trusted 747 px at 40-43.5 px, up to 4.8 px past the far end's 44.6, each a card at 523 mm)."""
import pytest

from psvs.dense.rig_cache import rectification
from psvs.io.params import load_rig
from psvs.optics.design import working_range
from psvs.optics.plate import derived_refraction_terms
from psvs.optics.search_range import RANGE_MARGIN_PX, disparity_range, working_disparities
from psvs.simulate.render import render
from tests.support.drift import wall


@pytest.mark.parametrize("name", ["default", "clear"])
@pytest.mark.parametrize("near_mm, far_mm", [(400.0, 1200.0), (1300.0, 2500.0)])
def test_the_span_brackets_eq_15_on_the_axis(name, near_mm, far_mm):
    """The rigs searched on the complex image's own rows (no rectification). Eq. (15) with x_l ~ 0 is eq. (12)
    with the baseline b + m: each end's disparity on the axis. Over the field the far end's least lies at or
    below it and the near end's largest at or above it, both within 1 %; the search's range
    (:func:`disparity_range`) holds the span, 4 px wider on the far side of eq. (12)."""
    rig = load_rig(name)
    m = rig.mirrors.refraction_m_mm
    m = derived_refraction_terms(rig)[1] if m is None else m
    k = (rig.mirrors.baseline_mm + m) / rig.mirrors.baseline_mm
    axis_far, axis_near = (d * k for d in working_range(rig, near_mm, far_mm).disparity_px)
    lo, hi = working_disparities(rig, near_mm, far_mm)
    assert axis_far * 0.99 <= lo <= axis_far + 0.05
    assert axis_near - 0.05 <= hi <= axis_near * 1.01
    s_lo, s_hi = disparity_range(rig, near_mm, far_mm)
    assert s_lo < lo - 3.0 and hi < s_hi + 1.5          # (the search adds a lag beyond each end too)


@pytest.mark.parametrize("z_mm, end", [(1200.0, "far"), (650.0, "near")])
def test_the_span_is_the_rendered_walls(z_mm, end):
    """A wall at the range's end, rendered (its truth's disparity at every pixel both views see): the far
    end's least disparity and the near end's largest, within 0.02 px."""
    rig = load_rig("default")
    truth = render(wall(z_mm, 3), rig, truth=True, seed=3).truth
    d = truth.disparity_left_px[truth.valid_left]
    assert d.size > 100_000
    if end == "far":
        assert working_disparities(rig, 400.0, z_mm)[0] == pytest.approx(d.min(), abs=0.02)
    else:
        assert working_disparities(rig, z_mm, 1200.0)[1] == pytest.approx(d.max(), abs=0.02)


@pytest.mark.parametrize("name", ["misaligned", "mv1440", "mv1440_misaligned"])
def test_on_a_build_the_span_is_on_the_rectified_grids(name):
    """A build: u'_l - u'_r on its rectification; the far end's least within 2 % of the rectified views'
    f' b' / z' there (the search's range without its margin) and the search's range holding the span."""
    rig = load_rig(name)
    rect = rectification(rig, 400.0, 1200.0)
    assert rect is not None
    lo, hi = working_disparities(rig, 400.0, 1200.0, rect)
    s_lo, s_hi = disparity_range(rig, 400.0, 1200.0, rect)
    assert s_lo < lo < hi < s_hi + 1.5
    assert lo == pytest.approx(s_lo + RANGE_MARGIN_PX, rel=0.02)
    assert hi == pytest.approx(s_hi - RANGE_MARGIN_PX, rel=0.02)


def test_a_range_before_the_views_overlap_has_no_span():
    """Nearer than the views overlap (the default rig: from 127 mm), no point is seen by both: None."""
    rig = load_rig("default")
    assert working_range(rig, 400.0, 1200.0).overlap_start_mm > 110.0
    assert working_disparities(rig, 100.0, 110.0) is None
    assert working_disparities(rig, 150.0, 160.0) is not None
