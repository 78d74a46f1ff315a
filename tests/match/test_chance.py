"""The automatic matcher's twins against chance (psvs.match.chance): the level against the closed form of an
exponential tail and its false-alarm rate on draws from one, the null bands' lags, and planted truth --
images without twins (noise, stripes, a checkerboard) refused, the paper's scenes answered."""
import math

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.match.chance import (
    ALPHA,
    FDR,
    GAP_PX,
    MIN_TAIL,
    Chance,
    NullCandidates,
    chance_level,
    null_bands,
    pair_level,
)
from psvs.match.correspondence import MatchParams, match_image
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from tests.support.geometry import EXAMPLES


@pytest.mark.parametrize("seed", range(3))
def test_the_level_on_an_exponential_tail_is_its_closed_form_and_keeps_its_false_alarm_rate(seed):
    """Null rows floor + Exp(beta), 5000 of them, drawn 400 times: the level for m tests is, in the median,
    the exact (1 - alpha) quantile of their largest, u0 + beta ln(m / alpha), or a little above it (the
    estimate's one-sigma margin); the largest of m fresh draws from the same tail exceeds the level read from
    its own null draw about alpha of the time or less (a 400-trial count: at most 3 alpha)."""
    rng = np.random.default_rng(seed)
    floor, beta, m = 10.0, rng.uniform(3, 30), int(rng.integers(100, 5000))
    exact = (floor - 1) + beta * math.log(m / ALPHA)           # the floored draws start a row lower
    levels, over = [], 0
    for _ in range(400):
        t = chance_level(np.floor(floor + rng.exponential(beta, 5000)), m, floor)
        levels.append(t)
        over += np.floor(floor + rng.exponential(beta, m)).max() > t
    assert exact <= np.median(levels) <= exact + 0.25 * beta * math.log(m / ALPHA)
    assert over <= 3 * ALPHA * 400


def test_the_level_without_a_tail_to_read():
    """No null candidate: one row under the floor (chance made none); fewer than MIN_TAIL: twice the
    strongest one's excess over it."""
    assert chance_level(np.zeros(0), 50, 10) == 9
    few = np.array([40.0, 12.0, 11.0])
    assert len(few) < MIN_TAIL and chance_level(few, 50, 10) == 9 + 2 * (40 - 9)


@pytest.mark.parametrize("seed", range(3))
def test_the_pair_level_keeps_its_false_discovery_rate_and_finds_the_twins(seed):
    """Benjamini-Hochberg against an independent count: null rows floor + Exp(beta) (3000), and a search of
    m chance candidates from the same tail plus 5-40 twins agreeing on 2-5 beta more rows than the null's
    expected strongest (beta ln 3000 beyond the floor), drawn 300 times. The share of chance candidates
    among those beyond the pair level averages at most FDR (+ 0.02 for the 300-trial mean); nine twins in
    ten are found; the level never lies below the strongest null candidate."""
    rng = np.random.default_rng(seed)
    floor, beta, m = 10.0, rng.uniform(3, 30), int(rng.integers(100, 3000))
    share, found = [], []
    for _ in range(300):
        null = np.floor(floor + rng.exponential(beta, 3000))
        twins = np.floor(floor + beta * (math.log(3000) + rng.uniform(2, 5, rng.integers(5, 41))))
        chance = np.floor(floor + rng.exponential(beta, m))
        level = pair_level(null, np.concatenate([chance, twins]), floor)
        assert level >= null.max()
        false, true = int((chance > level).sum()), int((twins > level).sum())
        share.append(false / max(false + true, 1))
        found.append(true / len(twins))
    assert np.mean(share) <= FDR + 0.02
    assert np.mean(found) >= 0.9


def test_the_pair_level_without_a_tail_to_read():
    """Fewer than MIN_TAIL null candidates: their strongest (a clean scene's outlines); none: a row under the
    floor."""
    assert pair_level(np.array([40.0, 12.0, 11.0]), np.array([100.0, 30.0]), 10) == 40
    assert pair_level(np.zeros(0), np.array([100.0]), 10) == 9


def test_a_backed_twin_is_asked_what_chance_makes_near_it():
    """Null candidates on a 10 px grid of boxes (5 x 5 px each) over two bands of 100 lags in all, rows 10 or
    40 alternately: near a box (24 px reach) the expected count is what lies there, per lag, times the 5
    lags of a backing window, counted independently here; a twin is backed beyond chance below FDR."""
    uu, vv = np.meshgrid(np.arange(0, 200, 10), np.arange(0, 200, 10))
    boxes = np.column_stack([uu.ravel(), vv.ravel(), uu.ravel() + 5, vv.ravel() + 5])
    rows = np.where(np.arange(len(boxes)) % 2 == 0, 10.0, 40.0)
    null = NullCandidates(rows, boxes, ((300.0, 349.0), (352.0, 401.0)))
    box = (100, 100, 104, 104)
    near = ((boxes[:, 0] <= 128) & (boxes[:, 2] >= 76) & (boxes[:, 1] <= 128) & (boxes[:, 3] >= 76))
    for r in (10.0, 40.0, 41.0):
        assert null.expected_near(r, box, 24) == pytest.approx((near & (rows >= r)).sum() * 5 / 100)
    chance = Chance(50.0, 45.0, 40.0, len(rows), 10, null.bands, 45.0, null)
    assert not chance.backed_beyond_chance(30.0, box, 24)        # chance makes about 6 as strong near it
    assert chance.backed_beyond_chance(41.0, box, 24)            # and none stronger than 40 rows
    assert not Chance(50.0, 45.0, 40.0, 0, 10, ()).backed_beyond_chance(41.0, box, 24)   # no null read


def test_null_bands_lie_beyond_the_range_as_wide_as_it():
    assert null_bands(86, 255, 640) == [(258, 427), (430, 599), (602, 639)]
    # nothing fits beyond: one band before the range, as wide as it where the lags allow
    assert null_bands(300, 600, 610) == [(GAP_PX, 297)]
    assert null_bands(100, 150, 160) == [(47, 97)]
    assert null_bands(5, 600, 610) == []


def _refused(img, rig):
    res = match_image(img, rig, params=MatchParams(subpixel=False))
    return not res.chance.answered and res.pairs == [] and res.chance.strongest_rows <= res.chance.level_rows


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("rig_name", ["default", "mv1440"])
def test_sensor_noise_holds_no_twin(seed, rig_name):
    rig = load_rig(EXAMPLES / "rigs" / f"{rig_name}.toml")
    w, h = rig.camera.image_size_px
    rng = np.random.default_rng(seed)
    assert _refused(rng.integers(0, 256, (h, w)).astype(np.uint8), rig)


@pytest.mark.parametrize("period", [20, 40, 64])
def test_stripes_and_a_checkerboard_hold_no_twin(period):
    """A repeating pattern agrees with itself at every multiple of its period, inside the range and beyond it
    alike: its twins cannot be told from its repetition."""
    rig = default_rig()
    yy, xx = np.mgrid[0:480, 0:640]
    stripes = (40 + 180 * (xx // period % 2)).astype(np.uint8)
    checker = (40 + 180 * ((xx // period + yy // period) % 2)).astype(np.uint8)
    assert _refused(stripes, rig) and _refused(checker, rig)


@pytest.mark.parametrize("scene", ["fig5a", "fig5b:distance_mm=650", "fig6"])
def test_the_papers_scenes_stand_above_chance(scene):
    rig = default_rig()
    img = render(builtin_scene(scene), rig, seed=1).image
    res = match_image(img, rig, params=MatchParams(subpixel=False))
    assert res.chance.answered and res.pairs
    assert res.chance.strongest_rows > res.chance.level_rows >= res.chance.null_max_rows
