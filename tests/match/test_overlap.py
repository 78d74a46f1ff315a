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
from psvs.optics.trace import trace_pixels
from psvs.simulate.builtin import regulated_light
from psvs.simulate.render import render
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.sensor import Sensor
from psvs.simulate.textures import Circles, Uniform


def overlap_scene(rig, shape, z_ring_mm, z_other_mm, offset_px, ring_xy_mm, ring_mm=(40.0, 18.0), size_mm=30.0):
    """The ring (outer and inner diameters ``ring_mm``, flat, facing the camera) at ``ring_xy_mm``, z_ring_mm;
    a disc of diameter ``size_mm`` (or a square of that side, turned 25 deg) at z_other_mm whose right-view
    centre lands ``offset_px`` (du, dv) from the ring's left-view centre (the ray of that pixel in the
    right view, a pinhole, met at z_other_mm). Returns (scene, other object's centre (3,) mm)."""
    ring_c = np.array([*ring_xy_mm, z_ring_mm])
    uv, _ = project_points(ring_c[None], rig, "left")
    rays = trace_pixels(uv + np.asarray(offset_px, float), rig, "right")
    t = (z_other_mm - rays.origins_mm[0, 2]) / rays.dirs[0, 2]
    other_c = rays.origins_mm[0] + t * rays.dirs[0]
    ring = SceneObject("disc", Pose(np.eye(3), ring_c), Circles(ring_mm[1], 20.0, 1, 0.08, 0.95),
                       radius_mm=ring_mm[0] / 2, name="ring")
    if shape == "disc":
        other = SceneObject("disc", Pose(np.eye(3), other_c), Uniform(0.95), radius_mm=size_mm / 2, name="disc")
    else:
        other = SceneObject("rectangle", Pose.from_euler_deg(other_c, [0.0, 0.0, 25.0]), Uniform(0.95),
                            size_mm=(size_mm, size_mm), name="square")
    light = regulated_light(0.5 * (z_ring_mm + z_other_mm))
    return Scene((ring, other), light, max(z_ring_mm, z_other_mm) + 500, Uniform(0.08)), other_c


def assert_both_paired(pairs, depths_mm) -> list[int]:
    """Every pair belongs to one of the objects (its median Z within 0.3 % of that object's depth) and
    both objects are paired (>= 15 pixel pairs each). Returns each pair's object (0: ring, 1: other)."""
    depths = np.array(depths_mm, float)
    owner = [int(np.argmin(np.abs(depths - p.median_z_mm()))) for p in pairs]
    for p, k in zip(pairs, owner):
        assert abs(p.median_z_mm() - depths[k]) <= 0.003 * depths[k], (k, len(p), p.median_z_mm())
    for k in (0, 1):
        assert sum(len(p) for p, o in zip(pairs, owner) if o == k) >= 15, k
    return owner


CASES = [  # shape, z ring, z other (mm), offset (du, dv) px, ring (x, y) mm, noise seed, sensor gain
    ("disc", 600, 650, (13, 0), (-30, 0), 1, 1.0),       # the disc's twin: a sliver in the ring's centre
    ("disc", 600, 650, (-14, 0), (-30, 0), 2, 1.0),
    ("disc", 600, 650, (0, 28), (-30, 0), 3, 1.0),       # ... on the outer outline and the inner contour
    ("disc", 600, 650, (18, -18), (0, -40), 4, 1.0),
    ("disc", 600, 650, (-22, 12), (-60, 30), 5, 1.6),    # overlap saturates the sensor
    ("disc", 500, 560, (-14, 0), (-30, 0), 6, 1.0),
    ("disc", 800, 900, (0, 28), (-50, 20), 7, 1.0),
    ("disc", 550, 700, (13, 0), (-80, 40), 8, 1.0),
    ("disc", 650, 600, (-14, 0), (-30, 0), 9, 1.0),      # the disc in front of the ring
    ("disc", 900, 820, (18, -18), (-30, 0), 10, 1.0),
    ("square", 600, 650, (0, 28), (-70, -50), 11, 1.0),
    ("square", 650, 600, (-14, 0), (-70, -50), 12, 1.0),
    ("square", 800, 900, (-22, 12), (-50, 30), 13, 1.0),
]


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

    twin = set().union(*(labels(p.right_px) for p, o in zip(m.pairs, owner) if o == 1))
    ring_left = set().union(*(labels(p.left_px) for p, o in zip(m.pairs, owner) if o == 0))
    assert twin & ring_left
    # the second object's left outline is not listed as an edge without a twin
    uv, _ = project_points(other_c[None], rig, "left")
    cu, cv = uv[0]
    assert not any(u0 <= cu <= u1 and v0 <= cv <= v1 for (u0, v0, u1, v1) in (u.bbox_px for u in m.unmatched))
