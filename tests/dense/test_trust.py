"""Which answers of a dense map the echo supports beyond chance (psvs.dense.trust): none on an image with no
echo (noise, a wall), most on real texture; the regions and the threshold on planted values."""
import math

import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.dense import DEFAULT, FAST, dense_disparity
from psvs.dense.evaluate import motorcycle, superimpose
from psvs.dense.trust import (
    ALPHA,
    TAIL,
    consistent_regions,
    echo_trust,
    excess_echo,
    null_image,
    region_threshold,
    trusted_maps,
)
from psvs.optics.search_range import disparity_range
from psvs.simulate.builtin import textured
from psvs.simulate.render import render

MODES = {"fast": FAST, "default": DEFAULT}


def test_regions_follow_a_surface_and_stop_at_jumps():
    """A ramp (1 px steps) is one region; a 2.5 px jump, a pixel without its own echo or a NaN cut it. A
    region's excess echo is the sum of its pixels' confidence minus chance's mean."""
    d = np.tile(np.arange(8.0), (4, 1))          # a slanted surface: 1 px per column
    conf = np.full_like(d, 0.5)
    labels, n = consistent_regions(d, conf)
    assert n == 1 and (labels == 0).all()
    d[:, 4:] += 1.5                              # a 2.5 px jump between columns 3 and 4
    conf[0, 0] = 0.0                             # no echo of its own
    d[3, 7] = np.nan
    labels, n = consistent_regions(d, conf)
    assert n == 2 and labels[0, 0] == -1 and labels[3, 7] == -1
    assert (labels[:, :4] == labels[1, 1]).sum() == 15 and (labels[:, 4:] == labels[0, 5]).sum() == 15
    per_pixel, per_region = excess_echo(d, conf, 0.3)
    assert sorted(per_region) == pytest.approx([15 * 0.2, 15 * 0.2])
    assert per_pixel[1, 1] == pytest.approx(3.0) and per_pixel[0, 0] == -np.inf


def test_the_threshold_is_chances_largest_times_its_tail():
    """e_max ((1 - alpha) / alpha)^tau over the positive excesses, tau Hill's estimator from the 30 largest
    over the 31st."""
    excess = np.concatenate([np.arange(1, 60) / 2, [400.0], [-5.0, -20.0]])
    e = np.sort(excess[excess > 0])[::-1]
    tau = np.mean(np.log(e[:TAIL])) - math.log(e[TAIL])
    assert TAIL == 30 and ALPHA == 0.01
    assert region_threshold(excess) == pytest.approx(400 * 99 ** tau)
    few = np.array([50.0, 20.0, 10.0, -3.0])                       # fewer than 31: all but the smallest
    assert region_threshold(few) == pytest.approx(50 * 99 ** (np.mean(np.log([50, 20])) - math.log(10)))
    assert region_threshold(np.array([-1.0])) == 0.0 and region_threshold(np.array([])) == 0.0
    assert region_threshold(np.array([100.0])) == pytest.approx(9900)


def test_the_null_pair_has_no_row_facing_itself():
    img = np.arange(12.0).reshape(6, 2)
    assert np.array_equal(null_image(img)[3:], img[:3]) and np.array_equal(null_image(img)[:3], img[3:])


@pytest.fixture(scope="module")
def no_echo():
    """Images with no echo structure, 640 x 480: independent random pixels, and a wall (grey 128, sensor noise)."""
    rng = np.random.default_rng(5)
    return {"noise": rng.integers(0, 256, (480, 640)).astype(np.float64),
            "wall": np.clip(128 + rng.normal(0, 2, (480, 640)), 0, 255)}


@pytest.mark.parametrize("mode", ["fast", "default"])
@pytest.mark.parametrize("kind", ["noise", "wall"])
def test_no_pixel_is_trusted_without_an_echo(no_echo, kind, mode):
    """The maps answer every pixel (as they did) with a confidence on a fifth of them; none is trusted:
    the largest region's excess echo stays below what chance makes on the same image, times its tail."""
    img = no_echo[kind]
    res = dense_disparity(img, 86, 255, params=MODES[mode])
    assert np.isfinite(res.disparity_left).all() and (res.confidence_left > 0).mean() > 0.1
    trust = echo_trust(img, res, MODES[mode])
    assert trust.count == 0 and not trust.trusted_right.any()
    assert trust.largest_excess < trust.min_excess and trust.null_largest_excess < trust.min_excess
    assert not (trusted_maps(res, trust).confidence_left > 0).any()


@pytest.fixture(scope="module")
def scene():
    rig = default_rig()
    rr = render(textured(), rig, truth=True)
    return rr.image, rr.truth, disparity_range(rig, 400, 1200)


@pytest.mark.parametrize("mode", ["fast", "default"])
def test_most_of_a_textured_scene_is_trusted(scene, mode):
    """The built-in textured scene through the default rig: most pixels the right view sees (measured 65 %
    fast, 86 % default) are trusted, and the trusted answers are right (within 2 px) more often than all."""
    img, truth, (lo, hi) = scene
    res = dense_disparity(img, lo, hi, params=MODES[mode])
    trust = echo_trust(img, res, MODES[mode])
    seen = truth.valid_left
    assert trust.trusted_left[seen].mean() > 0.6
    good = np.abs(res.disparity_left - truth.disparity_left_px) <= 2
    assert good[trust.trusted_left & seen].mean() > good[seen].mean()
    kept = trusted_maps(res, trust)
    np.testing.assert_array_equal(kept.disparity_left, res.disparity_left)
    assert np.array_equal(kept.confidence_left > 0, trust.trusted_left & (res.confidence_left > 0))


@pytest.mark.parametrize("mode", ["fast", "default"])
def test_most_of_motorcycle_is_trusted(mode):
    """Middlebury Motorcycle superimposed (the pair psvs dense-eval scores): most pixels with a twin in the
    image (measured 69 % fast, 86 % default) are trusted, and more often right than the rest."""
    left, right, gt = motorcycle()
    img = superimpose(left, right)
    res = dense_disparity(img, 0, 64, params=MODES[mode])
    trust = echo_trust(img, res, MODES[mode])
    x = np.arange(gt.shape[1])[None, :]
    seen = np.isfinite(gt) & (x - np.nan_to_num(gt) >= 0)
    assert trust.trusted_left[seen].mean() > 0.6
    good = np.abs(res.disparity_left - gt) <= 2
    assert good[trust.trusted_left & seen].mean() > good[seen & ~trust.trusted_left].mean() + 0.1


def test_blurred_noise_has_no_echo_either():
    """Noise blurred to the size of texture (sigma 1.5 px): chance correlations are larger, and so is chance's
    threshold, measured on the image itself."""
    rng = np.random.default_rng(6)
    img = np.clip(128 + 120 * cv2.GaussianBlur(rng.normal(size=(240, 320)), (0, 0), 1.5), 0, 255)
    res = dense_disparity(img, 20, 120, params=FAST)
    assert echo_trust(img, res, FAST).count == 0


@pytest.mark.parametrize("mode", ["fast", "default"])
def test_planted_layers_are_trusted(mode):
    """tests/dense/planted.py's two textured layers (320 x 200): almost every pixel with a twin is trusted
    (measured 94 % fast, 98 % default)."""
    from tests.dense.planted import layered_pair
    left, right, tl, _ = layered_pair()
    img = np.clip(np.rint(superimpose(left, right)), 0, 255)
    res = dense_disparity(img, 0, 40, params=MODES[mode])
    assert echo_trust(img, res, MODES[mode]).trusted_left[np.isfinite(tl)].mean() > 0.85


def test_on_a_build_chance_is_cut_to_the_views_fields():
    """The misaligned build (maps on the rectified grids): the textured scene is half trusted inside the
    left view's field (measured 49 %), noise through the same rig not at all."""
    from psvs.dense.build import dense_on_rig, rig_trust
    from psvs.io.params import load_rig
    rig = load_rig("misaligned")
    img = render(textured(), rig, seed=3).image
    dense = dense_on_rig(img, rig, params=FAST)
    trust = rig_trust(img, dense, FAST)
    inside = dense.rect.maps("left")[0] >= 0
    assert trust.trusted_left[inside].mean() > 0.35 and not trust.trusted_left[~inside].any()
    noise = np.random.default_rng(4).integers(0, 256, (480, 640)).astype(np.uint8)
    assert rig_trust(noise, dense_on_rig(noise, rig, params=FAST), FAST).count == 0


@pytest.mark.parametrize("mode", MODES)
def test_chance_run_in_the_maps_workspace_judges_as_in_fresh_memory(mode):
    """psvs batch keeps one workspace per worker: the maps and then chance's run in it, frame after frame
    (two images, two ranges), give the trust fresh memory gives, pixel for pixel."""
    from psvs.dense.workspace import Workspace
    from tests.dense.planted import layered_pair
    ws = Workspace()
    for seed, hi in ((0, 40), (3, 34), (0, 40)):
        left, right, _, _ = layered_pair(seed=seed)
        image = superimpose(left, right)
        want = echo_trust(image, dense_disparity(image, 0, hi, params=MODES[mode]), MODES[mode])
        res = dense_disparity(image, 0, hi, params=MODES[mode], workspace=ws)
        got = echo_trust(image, res, MODES[mode], workspace=ws)
        np.testing.assert_array_equal(got.trusted_left, want.trusted_left)
        np.testing.assert_array_equal(got.trusted_right, want.trusted_right)
        assert (got.min_excess, got.null_largest_excess, got.chance) == (want.min_excess, want.null_largest_excess,
                                                                          want.chance)
        assert got.trusted_left.any()
