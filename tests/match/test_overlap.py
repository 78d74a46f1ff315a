"""Automatic matching where one object's right view lands on another object's left view.

A bright ring (dark centre) and a bright disc (or a square) at different depths, the second placed so that
its right view overlaps the ring's left view: after the threshold their outlines merge, and only part of
the second object's twin outline is left on the edge map, merged with the ring's outer outline or with its
inner contour. Both objects must be paired, every pair's median Z within 0.3 % of the truth.
"""
import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.match.correspondence import match_image
from psvs.optics.project import project_points
from psvs.simulate.render import render
from psvs.simulate.sensor import Sensor
from tests.support.scenes import CASES, assert_both_paired, overlap_scene


@pytest.mark.parametrize("shape, z_ring, z_other, offset, ring_xy, seed, gain", CASES,
                         ids=[f"{c[0]}-{c[1]}-{c[2]}-du{c[3][0]}-dv{c[3][1]}-gain{c[6]}" for c in CASES])
def test_both_objects_paired_when_views_overlap(shape, z_ring, z_other, offset, ring_xy, seed, gain):
    rig = default_rig()
    scene, other_c = overlap_scene(rig, shape, z_ring, z_other, offset, ring_xy)
    res = render(scene, rig, seed=seed, sensor=Sensor(gain=gain))
    m = match_image(res.image, rig)
    owner = assert_both_paired(m.pairs, (z_ring, z_other))
    # the configuration: the second object's paired twin shares an edge component with the ring's left view
    _, lab = cv2.connectedComponents(m.edges.view(np.uint8), connectivity=8)

    def labels(pts):  # edge components at (within 1 px of) the refined points
        uv = np.rint(pts).astype(int)
        near = [lab[uv[:, 1] + dv, uv[:, 0] + du] for du in (-1, 0, 1) for dv in (-1, 0, 1)]
        return set(np.concatenate(near).tolist()) - {0}

    twin = set().union(*(labels(p.right_px) for p, o in zip(m.pairs, owner, strict=True) if o == 1))
    ring_left = set().union(*(labels(p.left_px) for p, o in zip(m.pairs, owner, strict=True) if o == 0))
    assert twin & ring_left
    # the second object's left outline is not listed as an edge without a twin
    uv, _ = project_points(other_c[None], rig, "left")
    cu, cv = uv[0]
    assert not any(u0 <= cu <= u1 and v0 <= cv <= v1 for (u0, v0, u1, v1) in (u.bbox_px for u in m.unmatched))
