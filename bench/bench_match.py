"""Matching, one core, 640x480 complex image of Fig. 5a: the paper's chain (median 3x3 + threshold 92 +
Roberts + one seeded match + triangulation) <= 2 ms per frame; automatic pairing (<= 20 edges) <= 10 ms.
The same image on the machine-vision camera (mv1440: 1440x1080, 5.06 times the pixels, disparities up to
515 px): the paper's chain <= 10 ms, match_image automatic <= 150 ms (the targets times the pixels)."""
import cv2

from psvs.imaging.pipeline import PAPER
from psvs.io.params import load_rig
from psvs.match.auto import match_auto
from psvs.match.correspondence import match_image
from psvs.match.seeded import match_seeded
from psvs.measure.triangulate import triangulate
from psvs.optics.search_range import disparity_range
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render

cv2.setNumThreads(1)
_states = {}


def _frame(rig_name: str = "default"):
    if rig_name not in _states:
        rig = load_rig(rig_name)
        img = render(builtin_scene("fig5a"), rig, seed=1).image
        rng = disparity_range(rig, 400.0, 1200.0)
        seed = match_auto(PAPER.run(img), rng, grey=img).pairs[0].left_px[0].astype(int)
        _states[rig_name] = dict(rig=rig, img=img, rng=rng, seed=seed)
    return _states[rig_name]


def _paper_chain(rig_name: str = "default"):
    s = _frame(rig_name)

    def run():
        edges = PAPER.run(s["img"])
        pair = match_seeded(edges, s["seed"], s["rng"])
        triangulate(pair.left_px, pair.right_px, s["rig"])
    return run


def _auto():
    s = _frame()
    return lambda: match_auto(PAPER.run(s["img"]), s["rng"], grey=s["img"])


def _full(seeded: bool, rig_name: str = "default"):
    def setup():
        s = _frame(rig_name)
        return lambda: match_image(s["img"], s["rig"], seed_px=s["seed"] if seeded else None)
    return setup


RATIOS = [("mv1440 1440x1080 / 640x480, paper chain (same run)",
           "mv1440 1440x1080: pipeline + seeded match + triangulation (paper chain)",
           "pipeline + seeded match + triangulation (paper chain)"),
          ("mv1440 1440x1080 / 640x480, match_image automatic (same run)",
           "mv1440 1440x1080: match_image automatic, sub-pixel + row correction + triangulation",
           "match_image automatic, sub-pixel + row correction + triangulation")]


def cases():
    return [
        ("pipeline + seeded match + triangulation (paper chain)", _paper_chain, 0.002),
        ("pipeline + automatic pairing (Fig. 5a)", _auto, 0.010),
        ("match_image seeded, sub-pixel + row correction + triangulation", _full(True), 0.010),
        ("match_image automatic, sub-pixel + row correction + triangulation", _full(False), 0.030),
        ("mv1440 1440x1080: pipeline + seeded match + triangulation (paper chain)",
         lambda: _paper_chain("mv1440"), 0.010),
        ("mv1440 1440x1080: match_image automatic, sub-pixel + row correction + triangulation",
         _full(False, "mv1440"), 0.150),
    ]
