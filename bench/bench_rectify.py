"""One core, 640x480 complex image of Fig. 5a through examples/rigs/misaligned.toml: what the dual
rectification adds to matching on a build, per frame (<= 2 ms: the edge pixels' rectified coordinates, the
two rectified images, pairs mapped back), and once per rig (reported); dense --fast on the build's two
rectified grids (the built-in textured scene): <= 100 ms with bench_dense's 64 disparities, as on the ideal
rig; the rig's whole working range (171 disparities on a 663x509 grid) reported; the depth and cloud of that
map (rig_cloud) through the build's depth table and by the exact trace it replaces, and the table's build,
reported."""
import cv2
import numpy as np

from psvs.dense.build import dense_on_rig, rig_cloud
from psvs.dense.depth_table import build_depth_table, exact_points
from psvs.dense.params import FAST
from psvs.imaging.pipeline import PAPER
from psvs.io.params import load_rig
from psvs.match.correspondence import match_image
from psvs.match.edges import edge_coords, roles_of
from psvs.optics.rectify import forget, rectify
from psvs.simulate.builtin import builtin_scene, textured
from psvs.simulate.render import render

cv2.setNumThreads(1)
_state = {}


def _frame():
    if not _state:
        rig = load_rig("misaligned")
        img = render(builtin_scene("fig5a"), rig, seed=1).image
        rect = rectify(rig)
        pairs = match_image(img, rig).pairs
        _state.update(rig=rig, img=img, rect=rect, edges=PAPER.run(img), pairs=pairs)
    return _state


def _once():
    rig = load_rig("misaligned")

    def run():
        forget()
        r = rectify(rig)
        r.pixel_table("left"), r.pixel_table("right"), r.maps("left"), r.maps("right")
    return run


def _per_frame():
    s = _frame()
    u, v = edge_coords(s["edges"])
    rect = s["rect"]
    rect_pairs = [(rect.to_rectified(p.left_px, "left"), rect.to_rectified(p.right_px, "right")) for p in s["pairs"]]
    img = s["img"]

    def run():
        roles_of(u, v, rect)
        pts = np.concatenate([np.vstack(p) for p in rect_pairs])
        (c0, r0), (c1, r1) = np.floor(pts.min(axis=0)).astype(int) - 6, np.ceil(pts.max(axis=0)).astype(int) + 7
        window = (max(0, r0), r1, max(0, c0), c1)
        rect.remap_fast(img, "left", window), rect.remap_fast(img, "right", window)
        for lp, rp in rect_pairs:
            rect.lookup(lp, "left"), rect.lookup(rp, "right")
    return run


def _match(auto: bool):
    def setup():
        s = _frame()
        seed = tuple(np.rint(s["pairs"][0].left_px[0]).astype(int))
        return lambda: match_image(s["img"], s["rig"], seed_px=None if auto else seed)
    return setup


def _dense_fast(d_range=None):
    def setup():
        rig = load_rig("misaligned")
        img = render(textured(), rig, seed=1).image
        dense_on_rig(img, rig, params=FAST, d_range=d_range)    # the rectification and its tables, once per rig
        return lambda: dense_on_rig(img, rig, params=FAST, d_range=d_range)
    return setup


def _cloud(table: bool):
    def setup():
        rig = load_rig("misaligned")
        dense = dense_on_rig(render(textured(), rig, seed=1).image, rig, params=FAST)
        if table:
            rig_cloud(dense, rig)                                # the table, once per rig
            return lambda: rig_cloud(dense, rig)
        d = dense.result.disparity_left.astype(np.float64)
        v, u = np.nonzero(np.isfinite(d) & (d > 0))
        uv = np.column_stack([u, v]).astype(np.float64)
        return lambda: exact_points(dense.rect, uv, d[v, u])    # rig_cloud's triangulation before the table
    return setup


def _table():
    rect = rectify(load_rig("misaligned"))
    return lambda: build_depth_table(rect)


CLOUD_TABLE = "rig_cloud of that map: cloud through the depth table"
CLOUD_EXACT = "rig_cloud of that map: cloud by the exact trace (before the table)"


def cases():
    return [
        ("rectify a build: fit, pixel tables, remaps (once per rig)", _once, float("inf")),
        ("per frame: edge roles + 2 rectified images + pairs back", _per_frame, 0.002),
        ("match_image seeded on the build, sub-pixel + exact triangulation", _match(False), float("inf")),
        ("match_image automatic on the build, sub-pixel + exact triangulation", _match(True), float("inf")),
        ("dense --fast on the build, 663x509 rectified grids, 64 disparities (as bench_dense)",
         _dense_fast((100.0, 164.0)), 0.100),
        ("dense --fast on the build, the rig's whole 400-1200 mm range (171 disparities)", _dense_fast(),
         float("inf")),
        (CLOUD_TABLE, _cloud(True), float("inf")),
        (CLOUD_EXACT, _cloud(False), float("inf")),
        ("the build's depth table (once per rig; then from the cache folder)", _table, float("inf")),
    ]
