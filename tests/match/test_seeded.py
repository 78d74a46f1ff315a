"""The paper's algorithm (III.3 steps 2-8) on planted edge maps: a shape and its twin d px to the left."""
import cv2
import numpy as np
import pytest

from psvs.match.auto import match_auto
from psvs.match.seeded import match_seeded
from tests.support.scenes import POLY, paper_edges


def edge_map(shapes):
    """Thin 8-connected outlines (cv2.polylines)."""
    img = np.zeros((480, 640), np.uint8)
    for pts in shapes:
        cv2.polylines(img, [pts.astype(np.int32)], True, 255, 1)
    return img > 0


@pytest.mark.parametrize("make, connectivity", [(paper_edges, 4), (edge_map, 8)])
def test_seed_finds_the_twin_at_its_disparity(make, connectivity):
    edges = make([POLY, POLY - [130, 0], POLY + [150, 40]])   # twin at d = 130, a distractor elsewhere
    one = make([POLY])
    v, u = np.nonzero(one)
    pair = match_seeded(edges, (u[0], v[0]), (80, 250), connectivity=connectivity)
    assert pair.shape_disparity_px == 130
    assert len(pair) >= 0.9 * one.sum()
    assert np.all(pair.disparity_px == 130)
    assert np.array_equal(pair.left_px[:, 1], pair.right_px[:, 1])   # same rows


def test_pairing_follows_a_drifting_disparity():
    """The twin is the shape stretched by 10 % in u (a slanted surface): disparity varies along the edge."""
    twin = POLY.astype(float).copy()
    twin[:, 0] = 170 + (twin[:, 0] - 300) * 1.1
    edges = paper_edges([POLY, twin])
    one = paper_edges([POLY])
    v, u = np.nonzero(one)
    pair = match_seeded(edges, (u[0], v[0]), (60, 200))
    expected = POLY[:, 0] - (170 + (POLY[:, 0] - 300) * 1.1)
    assert pair.disparity_px.min() >= expected.min() - 2 and pair.disparity_px.max() <= expected.max() + 2
    assert len(pair) >= 0.8 * one.sum()


def test_auto_pairs_and_reports_unmatched():
    lonely = np.array([[100, 380], [140, 380], [140, 440], [100, 440]])
    edges = paper_edges([POLY, POLY - [130, 0], lonely])
    m = match_auto(edges, (80, 250))
    assert len(m.pairs) == 1 and m.pairs[0].shape_disparity_px == 130
    assert len(m.unmatched) == 1
    u0, v0, u1, v1 = m.unmatched[0].bbox_px
    assert abs(u0 - 100) <= 1 and abs(v0 - 380) <= 1 and abs(u1 - 140) <= 1 and abs(v1 - 440) <= 1


@pytest.mark.parametrize("seed, message", [
    ((10, 10), r"seed \(10, 10\) is not on an edge pixel"),
    ((700, 10), r"seed \(700, 10\) is outside the 640x480 image"),
    (("a", 3), "seed must be two numbers"),
])
def test_bad_seeds(seed, message):
    with pytest.raises(ValueError, match=message):
        match_seeded(edge_map([POLY]), seed, (80, 250))


def test_no_twin_gives_no_pair_and_bad_options():
    pair = match_seeded(edge_map([POLY]), (300, 100), (80, 250))
    assert len(pair) == 0
    with pytest.raises(ValueError, match="n_seeds must be in 2..100"):
        match_seeded(edge_map([POLY]), (300, 100), (80, 250), n_seeds=1)
    with pytest.raises(ValueError, match="0 < d_min < d_max"):
        match_auto(edge_map([POLY]), (50, 10))
