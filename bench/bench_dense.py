"""Issue 6, both cores: dense disparity of a 640x480 complex image, 64 disparities. ``--fast`` <= 100 ms per
frame; the default mode and the view separation are reported. The frame is the Middlebury Motorcycle pair
superimposed (0.5 L + 0.5 R), cropped to 640x480."""
import cv2
import numba

from psvs.dense import dense_disparity, separate_views
from psvs.dense.evaluate import motorcycle, superimpose

cv2.setNumThreads(2)
numba.set_num_threads(2)
_state = {}


def _frame():
    if not _state:
        left, right, _ = motorcycle()
        c = superimpose(left, right)[10:490, 50:690]
        _state.update(c=c, res=dense_disparity(c, 0, 64))
    return _state


def _dense(fast: bool):
    def setup():
        c = _frame()["c"]
        return lambda: dense_disparity(c, 0, 64, fast=fast)
    return setup


def _separate():
    s = _frame()
    return lambda: separate_views(s["c"], s["res"].disparity_left, 0.5, s["res"].disparity_right)


def cases():
    return [("dense --fast, 640x480, 64 disparities, 2 cores", _dense(True), 0.100),
            ("dense (default mode), 640x480, 64 disparities, 2 cores", _dense(False), float("inf")),
            ("view separation, 640x480 (reported)", _separate, float("inf"))]
