"""Matching, one core, 640x480 complex image of Fig. 5a: the paper's chain (median 3x3 + threshold 92 +
Roberts + one seeded match + triangulation) <= 2 ms per frame; automatic pairing (<= 20 edges) <= 10 ms."""
import cv2

from psvs import default_rig
from psvs.imaging.pipeline import PAPER
from psvs.match.auto import match_auto
from psvs.match.correspondence import match_image
from psvs.match.seeded import match_seeded
from psvs.measure.triangulate import triangulate
from psvs.optics.search_range import disparity_range
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render

cv2.setNumThreads(1)
_state = {}


def _frame():
    if not _state:
        rig = default_rig()
        img = render(builtin_scene("fig5a"), rig, seed=1).image
        rng = disparity_range(rig, 400.0, 1200.0)
        seed = match_auto(PAPER.run(img), rng, grey=img).pairs[0].left_px[0].astype(int)
        _state.update(rig=rig, img=img, rng=rng, seed=seed)
    return _state


def _paper_chain():
    s = _frame()

    def run():
        edges = PAPER.run(s["img"])
        pair = match_seeded(edges, s["seed"], s["rng"])
        triangulate(pair.left_px, pair.right_px, s["rig"])
    return run


def _auto():
    s = _frame()
    return lambda: match_auto(PAPER.run(s["img"]), s["rng"], grey=s["img"])


def _full(seeded: bool):
    def setup():
        s = _frame()
        return lambda: match_image(s["img"], s["rig"], seed_px=s["seed"] if seeded else None)
    return setup


def cases():
    return [
        ("pipeline + seeded match + triangulation (paper chain)", _paper_chain, 0.002),
        ("pipeline + automatic pairing (Fig. 5a)", _auto, 0.010),
        ("match_image seeded, sub-pixel + row correction + triangulation", _full(True), 0.010),
        ("match_image automatic, sub-pixel + row correction + triangulation", _full(False), 0.030),
    ]
