"""Scores and the acceptance runs: Middlebury Motorcycle (real photographs) and a simulated PSVS scene."""
from dataclasses import replace

import numpy as np
import pytest

from psvs.dense import dense_disparity, disparity_cloud, psnr_db, separate_views
from psvs.dense.evaluate import (
    check_truth_fits,
    disparity_scores,
    evaluate_pair,
    mirrored,
    motorcycle,
    sgbm_reference,
    superimpose,
    truth_fit,
)
from psvs.optics.search_range import disparity_range
from psvs.simulate.builtin import textured
from psvs.simulate.render import render
from psvs.simulate.sensor import Sensor, expose
from tests.dense.planted import layered_pair


def test_scores_count_missing_answers_as_wrong():
    truth = np.array([[10.0, 10.0, 10.0, 10.0, np.nan]])
    est = np.array([[10.5, 11.5, 13.0, np.nan, 99.0]])
    s = disparity_scores(est, truth)
    assert s["bad1_pct"] == pytest.approx(75.0)       # 11.5, 13 and NaN
    assert s["bad2_pct"] == pytest.approx(50.0)       # 13 and NaN
    assert s["mae_px"] == pytest.approx((0.5 + 1.5 + 3.0) / 3)
    assert s["coverage_pct"] == pytest.approx(75.0)
    with pytest.raises(ValueError, match="no valid pixel"):
        disparity_scores(est, np.full_like(truth, np.nan))
    with pytest.raises(ValueError, match="shape"):
        disparity_scores(est[:, :3], truth)


def test_superimpose_and_the_sgbm_reference_on_a_planted_pair():
    left, right, tl, _ = layered_pair()
    c = superimpose(left, right, 0.3)
    np.testing.assert_allclose(c, 0.7 * left + 0.3 * right)
    with pytest.raises(ValueError, match="one size"):
        superimpose(left, right[:, :10])
    s = disparity_scores(sgbm_reference(left, right, 40), tl)   # the separate pair is easy for SGBM
    assert s["bad2_pct"] < 15 and s["mae_px"] < 0.5


def test_the_truth_fit_is_one_on_an_exact_shift_and_falls_off_it():
    """truth_fit against its closed form: a right view that is the left shifted by a whole 12 px maps back
    exactly (correlation 1 over the pixels whose twin is in the image); shifted 5 px further, white noise's
    band-passed texture no longer correlates (|r| < 0.05)."""
    rng = np.random.default_rng(4)
    scene = rng.uniform(0, 255, (120, 212))
    left, right = scene[:, :-12], scene[:, 12:]             # right(x - 12) = left(x): the left pixel x at x - 12
    truth = np.full(left.shape, 12.0)
    inner = np.full(left.shape, np.nan)                     # clear of the band-pass's borders (7 px) in both views
    inner[8:-8, 20:-8] = 12.0
    assert truth_fit(left, right, inner) == pytest.approx(1.0, abs=1e-6)
    assert abs(truth_fit(left, right, truth, 5.0)) < 0.05
    check_truth_fits(left, right, truth)


@pytest.mark.parametrize("mistake", ["views swapped", "one image twice", "truth at half scale",
                                     "truth of another pair"])
def test_a_truth_that_does_not_map_the_pair_is_refused(mistake):
    """An adversarial trial (issue 41): dense-eval scored a planted pair with its views swapped at psvs's own
    2.1 % bad-2 (the superimposed image is the same) while the pair was the other way round; a truth at half
    scale scored every method 100 % bad; one image given twice was scored. Each is refused before any work,
    naming the correlations."""
    left, right, truth, _ = layered_pair()
    check_truth_fits(left, right, truth)
    other, _, _, _ = layered_pair(seed=7)
    args = {"views swapped": (right, left, truth), "one image twice": (left, left, truth),
            "truth at half scale": (left, right, truth / 2), "truth of another pair": (other, right, truth)}[mistake]
    with pytest.raises(ValueError, match=r"^the ground truth does not map the right view onto the left: warped by "
                                         r"it, the right view correlates -?\d\.\d\d with the left, and -?\d\.\d\d "
                                         r"with the truth shifted 3-15 px \(chance\)"):
        evaluate_pair(*args, 0, 40)


@pytest.fixture(scope="module")
def moto():
    left, right, gt = motorcycle()
    return left, right, gt, evaluate_pair(left, right, gt, 0, 64)


def test_motorcycle_scores(moto):
    """The acceptance data set (Middlebury Motorcycle): the target is bad-2 <= 20 % (goal 15 %); measured 16.6 %."""
    left, _, gt, ev = moto
    assert left.shape == gt.shape == (500, 741)
    ours, fast, ref = (ev.scores[k] for k in ("psvs dense", "psvs dense --fast", "StereoSGBM, separate pair"))
    assert ours["bad2_pct"] < 17.5 and ours["coverage_pct"] == 100.0
    assert fast["bad2_pct"] < 25.0
    assert 17.0 < ref["bad2_pct"] < 21.0            # StereoSGBM's reference figure on this pair: 18 %
    assert ev.psnr_left_db > 20.8 and ev.psnr_right_db > 20.8   # the pair itself is consistent to 22.8 dB
    assert ev.psnr_left_db > psnr_db(ev.complex_image, left) + 1.5


def test_mirrored_pair_truth_is_the_right_views_disparity():
    left, right, tl, tr = layered_pair()
    ml, mr, mt = mirrored(left, right, tl)
    np.testing.assert_array_equal(ml, np.fliplr(right))
    np.testing.assert_array_equal(mr, np.fliplr(left))
    seen = np.isfinite(mt)
    assert seen.mean() > 0.85
    np.testing.assert_array_equal(mt[seen], np.fliplr(tr)[seen])   # the right view's own truth, mirrored


def test_mirrored_motorcycle_scores(moto):
    """The same photographs in a mirror: every ghost falls on the other side. Measured 12.5 % (StereoSGBM on
    the separate mirrored pair: see docs/dense.md)."""
    left, right, gt, _ = moto
    ml, mr, mt = mirrored(left, right, gt)
    res = dense_disparity(superimpose(ml, mr), 0, 64)
    assert disparity_scores(res.disparity_left, mt)["bad2_pct"] < 13.5


@pytest.mark.slow
def test_simulated_psvs_scene():
    """The built-in photo-textured scene through the paper's rig, against the renderer's ground truth."""
    from psvs import default_rig

    rig = default_rig()
    rr = render(textured(), rig, truth=True)
    lo, hi = disparity_range(rig, 400, 1200)
    res = dense_disparity(rr.image, lo, hi)
    truth = rr.truth.disparity_left_px
    assert disparity_scores(res.disparity_left, truth)["bad2_pct"] < 10.0
    # depth of the well-matched pixels through eqs. (15)-(17) against the true depth
    good = np.abs(res.disparity_left - truth) <= 2
    cloud = disparity_cloud(np.where(good, res.disparity_left, np.nan), rig)
    z_err = np.abs(cloud.depth_mm - rr.truth.depth_left_mm)[good] / rr.truth.depth_left_mm[good]
    assert np.nanmedian(z_err) < 0.004
    # separated views against each view exposed alone (no noise), the same sensor otherwise. With the true
    # disparity they gain 4 dB over the mixture; with ours they only hold the mixture's level (docs/dense.md)
    clean = replace(Sensor(), shot_noise=False, read_noise_e=0.0)
    true_l, true_r = expose(rr.left, clean), expose(rr.right, clean)
    base_l, base_r = psnr_db(rr.image, true_l), psnr_db(rr.image, true_r)
    lv, rv = separate_views(rr.image, truth, 0.5, rr.truth.disparity_right_px)
    assert psnr_db(lv, true_l) > base_l + 3.0 and psnr_db(rv, true_r) > base_r + 3.0
    lv, rv = separate_views(rr.image, res.disparity_left, 0.5, res.disparity_right)
    assert psnr_db(lv, true_l) > base_l - 0.5 and psnr_db(rv, true_r) > base_r - 0.5
