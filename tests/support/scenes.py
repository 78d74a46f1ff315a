"""Scenes and points the tests of several packages share: seeds on a disc's rim, image centroids, flat discs
and overlapping objects for matching, the paper's edge pipeline."""
import cv2
import numpy as np

from psvs.optics.project import project_points
from psvs.optics.trace import trace_pixels
from psvs.simulate.builtin import regulated_light
from psvs.simulate.scene import Lighting, Pose, Scene, SceneObject
from psvs.simulate.textures import Circles, Uniform


def rim_seed(rig, scene, position_mm, offset_px=(2.0, 1.0)):
    """A point near the disc's rim in the left view (its leftmost rim point, projected, then moved by
    offset_px: a user's double-click is never exactly on the edge)."""
    disc = scene.objects[0]
    c = disc.pose.position_mm - position_mm
    uv, ok = project_points([[c[0] - disc.radius_mm, c[1], c[2]]], rig, "left")
    assert ok[0]
    return uv[0] + offset_px


def centroid(img, around, half=60):
    u0, v0 = np.round(around).astype(int)
    win = img[v0 - half:v0 + half + 1, u0 - half:u0 + half + 1]
    vv, uu = np.mgrid[v0 - half:v0 + half + 1, u0 - half:u0 + half + 1]
    return np.array([(win * uu).sum() / win.sum(), (win * vv).sum() / win.sum()])


def flat_discs_scene():
    """Fronto-parallel white discs at 450-1100 mm whose two views stay apart."""
    objs = (SceneObject("disc", Pose(np.eye(3), np.array([-40.0, -70.0, 450.0])), Uniform(0.95), radius_mm=18),
            SceneObject("disc", Pose(np.eye(3), np.array([60.0, 80.0, 700.0])), Uniform(0.95), radius_mm=25),
            SceneObject("disc", Pose(np.eye(3), np.array([10.0, 10.0, 1100.0])), Uniform(0.95), radius_mm=40))
    return Scene(objs, regulated_light(700.0), 1500.0, Uniform(0.1))


POLY = np.array([[300, 100], [380, 130], [400, 260], [330, 330], [290, 250]], np.int32)


def paper_edges(shapes):
    """Filled shapes through the paper's pipeline (median, threshold 92, Roberts): its edges are 4-connected."""
    from psvs.imaging.pipeline import PAPER
    img = np.full((480, 640), 20, np.uint8)
    for pts in shapes:
        cv2.fillPoly(img, [np.rint(pts).astype(np.int32)], 200)
    return PAPER.run(img)


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
    for p, k in zip(pairs, owner, strict=True):
        assert abs(p.median_z_mm() - depths[k]) <= 0.003 * depths[k], (k, len(p), p.median_z_mm())
    for k in (0, 1):
        assert sum(len(p) for p, o in zip(pairs, owner, strict=True) if o == k) >= 15, k
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


FLAT_LIGHT = Lighting(ambient=1.0, lamp=0.0, shadows=False)


def white_disc_scene(x_mm=-20.0, y_mm=10.0, z_mm=600.0, radius_mm=15.0):
    """A white fronto-parallel disc on a black backdrop, lit evenly: radiance 1 on the disc, 0 elsewhere."""
    disc = SceneObject("disc", Pose(np.eye(3), np.array([x_mm, y_mm, z_mm])), Uniform(1.0), radius_mm=radius_mm)
    return Scene((disc,), FLAT_LIGHT, z_mm + 300, Uniform(0.0))
