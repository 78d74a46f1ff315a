"""Matching on a build: twins 3-16 rows apart in the complex image are paired on the rows
of the dual rectification, refined there and triangulated with the build's exact model.

Scenes: separated flat discs at 450-1100 mm and the overlap scenes of tests/match/test_overlap.py, on the
shipped misaligned build and on random builds (tilts 0.1-0.3 deg, shifts up to 0.8 mm, a real lens); every
object paired, every pair's median Z within 0.3 % of the truth, and each point near its object's plane.
"""
import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.match.correspondence import MatchParams, match_image
from psvs.match.seeded import match_seeded
from psvs.measure.triangulate import default_model, triangulate
from psvs.optics.project import project_points
from psvs.optics.search_range import disparity_range, rectification_for
from psvs.simulate.render import render
from psvs.simulate.sensor import Sensor
from tests.support.rig_draws import random_build
from tests.support.scenes import CASES, assert_both_paired, flat_discs_scene, overlap_scene

BUILDS = {"misaligned": lambda: load_rig("misaligned"),
          **{f"random{s}": (lambda s=s: random_build(s)[0]) for s in (3, 6)}}
DISCS = np.array([[-40.0, -70.0, 450.0], [60.0, 80.0, 700.0], [10.0, 10.0, 1100.0]])   # flat_discs_scene


@pytest.mark.parametrize("name", sorted(BUILDS))
def test_separated_discs_pair_on_a_build(name):
    rig = BUILDS[name]()
    # the rows really disagree: each disc centre's twin is rows away in the complex image
    uv_l, _ = project_points(DISCS, rig, "left")
    uv_r, _ = project_points(DISCS, rig, "right")
    assert np.abs(uv_l[:, 1] - uv_r[:, 1]).max() > 3
    m = match_image(render(flat_discs_scene(), rig, seed=2).image, rig)
    z = np.array([p.median_z_mm() for p in m.pairs])
    assert len(m.pairs) == 3 and not m.unmatched
    np.testing.assert_allclose(np.sort(z), DISCS[:, 2], rtol=0.003)
    for p in m.pairs:
        k = int(np.argmin(np.abs(DISCS[:, 2] - p.median_z_mm())))
        err = np.abs(p.points_mm[:, 2] - DISCS[k, 2])
        assert np.nanpercentile(err, 90) < 0.01 * DISCS[k, 2]       # each point, not only the median
        assert len(p) > 120        # (a disc's top and bottom: rows along the edge no steeper pixel pins, dropped)
        # pixels are complex-image pixels: each left point projects back onto its left pixel
        uv, ok = project_points(p.points_mm, rig, "left")
        assert np.nanmedian(np.abs(uv[ok, 0] - p.left_px[ok, 0])) < 0.5


@pytest.mark.parametrize("case", CASES[::3], ids=[f"{c[0]}-{c[1]}-{c[2]}" for c in CASES[::3]])
def test_overlapping_views_pair_on_a_build(case):
    shape, z_ring, z_other, offset, ring_xy, seed, gain = case
    rig = load_rig("misaligned")
    scene, _ = overlap_scene(rig, shape, z_ring, z_other, offset, ring_xy)
    m = match_image(render(scene, rig, seed=seed, sensor=Sensor(gain=gain)).image, rig)
    assert_both_paired(m.pairs, (z_ring, z_other))


def test_seeded_matching_on_a_build():
    """The paper's algorithm from one seed on the nearest disc's left outline."""
    rig = load_rig("misaligned")
    img = render(flat_discs_scene(), rig, seed=3).image
    top = DISCS[0] + [0.0, -18.0, 0.0]                            # the disc's top rim point
    uv, _ = project_points(top[None], rig, "left")
    m0 = match_image(img, rig, params=MatchParams(subpixel=False))
    edges = m0.edges
    v0 = int(np.rint(uv[0, 1]))
    cols = np.flatnonzero(edges[v0 - 1:v0 + 2].any(axis=0))
    seed = (int(cols[np.argmin(np.abs(cols - uv[0, 0]))]), v0)
    seed = (seed[0], v0 - 1 + int(np.flatnonzero(edges[v0 - 1:v0 + 2, seed[0]])[0]))
    m = match_image(img, rig, seed_px=seed)
    assert len(m.pairs) == 1 and len(m.pairs[0]) > 100
    assert abs(m.pairs[0].median_z_mm() - 450.0) < 0.003 * 450.0
    err = np.abs(m.pairs[0].points_mm[:, 2] - 450.0)
    assert np.nanpercentile(err, 90) < 4.5
    # the paper's same-row search on the complex image pairs wrong pixels on this build: off the plane
    rect = rectification_for(rig, 400.0, 1200.0)
    rng = disparity_range(rig, 400.0, 1200.0, rect)
    wrong = match_seeded(edges, seed, rng)
    z = triangulate(wrong.left_px, wrong.right_px, rig, model="exact").points_mm[:, 2]
    assert np.nanpercentile(np.abs(z - 450.0), 90) > 4.5


def test_builds_default_to_the_exact_model():
    assert default_model(load_rig("misaligned")) == "exact"
    assert default_model(load_rig("default")) == "refraction"
    assert rectification_for(load_rig("default"), 400.0, 1200.0) is None
