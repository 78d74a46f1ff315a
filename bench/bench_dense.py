"""Dense disparity of a 640x480 complex image on both cores: the Middlebury Motorcycle pair superimposed
(0.5 L + 0.5 R) and cropped to 640x480. Default mode <= 300 ms at 64 disparities and <= 600 ms at the rig's
160; ``--fast`` <= 33 ms (camera rate); view separation <= 300 ms. OpenCV's StereoSGBM (3-way,
MODE_SGBM_3WAY) on the *separate* pair (same crop, 64 disparities) is timed in the same run twice: on all
cores, as psvs uses them (the reference ratio), and on one thread (the figure first quoted for it).

1440x1080 (the mv1440 rig, its whole 400-1200 mm, through dense_on_rig: the complex image resampled on the
two rectified grids, the coarse-to-fine pyramid of psvs.dense.pyramid): the default mode and --fast on a
rendered frame (photo cards before a photo wall), against StereoSGBM 3-way on all cores on a separate pair
of the same size (the two views rendered alone) and the same disparity count rounded up to a multiple of
16. Targets as ratios in the same run: default <= 5 x StereoSGBM, --fast <= 1 x."""
import math
import os

import cv2
import numba

from psvs.dense import dense_disparity, separate_views
from psvs.dense.evaluate import motorcycle, sgbm_reference, superimpose
from psvs.dense.params import DEFAULT, FAST, DenseParams
from psvs.dense.workspace import Workspace

numba.set_num_threads(2)
_state = {}


def _frame():
    if not _state:
        left, right, _ = motorcycle()
        crop = (slice(10, 490), slice(50, 690))
        c = superimpose(left, right)[crop]
        _state.update(c=c, left=left[crop], right=right[crop], res=dense_disparity(c, 0, 64))
    return _state


def _dense(params: DenseParams, d_max: float = 64):
    def setup():
        cv2.setNumThreads(2)
        c = _frame()["c"]
        ws = Workspace()     # as a live loop keeps it from frame to frame
        return lambda: dense_disparity(c, 0, d_max, params=params, workspace=ws)
    return setup


def _separate():
    s = _frame()
    return lambda: separate_views(s["c"], s["res"].disparity_left, 0.5, s["res"].disparity_right)


def _cores() -> int:
    """The cores this process may run on (all of them: what psvs's two Numba threads use here)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _sgbm(threads: int):
    """StereoSGBM 3-way on the separate pair with OpenCV on ``threads`` threads, the previous setting
    restored after each call. (cv2.setNumThreads(0) would run OpenCV sequentially, not on all cores.)"""
    def setup():
        s = _frame()

        def run():
            previous = cv2.getNumThreads()
            cv2.setNumThreads(threads)
            try:
                sgbm_reference(s["left"], s["right"], 64)
            finally:
                cv2.setNumThreads(previous)
        return run
    return setup


DEFAULT_CASE = "dense (default mode), 640x480, 64 disparities, 2 cores"
SGBM_ALL = "OpenCV StereoSGBM 3-way (MODE_SGBM_3WAY) on the separate pair, 64 disparities, all cores"
SGBM_ONE = "OpenCV StereoSGBM on the separate pair, 64 disparities, 1 thread"
#: The first ratio is the reference: both methods on all the cores they can use.
RATIOS = [("default mode / StereoSGBM 3-way all cores (same image, same run)", DEFAULT_CASE, SGBM_ALL),
          ("default mode / StereoSGBM 3-way 1 thread (same image, same run)", DEFAULT_CASE, SGBM_ONE)]


def _live_dense():
    """psvs live --dense's per-frame work: the fast mode over the default rig's whole working range
    (400-1200 mm) and the strided cloud, on a rendered photo wall at 700 mm."""
    from psvs import default_rig
    from psvs.live.dense import DenseSensor
    from psvs.simulate.builtin import photo_texture, regulated_light
    from psvs.simulate.render import render
    from psvs.simulate.scene import Scene
    rig = default_rig()
    frame = render(Scene((), regulated_light(700.0), 700.0, photo_texture("grass", (1400.0, 1050.0)), "wall"), rig,
                   seed=1).image
    sensor = DenseSensor(rig)
    return lambda: sensor.step(frame)


MV_RIG = "mv1440"
MV_NEAR_MM, MV_FAR_MM = 400.0, 1200.0
_mv = {}


def _mv_frame():
    """A 1440x1080 complex image through mv1440 (photo cards at 600 and 800 mm before a photo wall at
    1100 mm, 1 sample a pixel), each view alone, and the disparity count the dense search covers."""
    if not _mv:
        from psvs.io.params import load_rig
        from psvs.optics.search_range import disparity_range, rectification_for
        from psvs.simulate.builtin import photo_texture, pose_at, regulated_light
        from psvs.simulate.render import render
        from psvs.simulate.scene import Scene, SceneObject
        rig = load_rig(MV_RIG)
        cards = (SceneObject("rectangle", pose_at(-70, -20, 600, 0, 10, 5), photo_texture("astronaut", (120, 90)),
                             size_mm=(120, 90)),
                 SceneObject("rectangle", pose_at(60, 40, 800, 0, -15, -4), photo_texture("coffee", (150, 110)),
                             size_mm=(150, 110)))
        back = photo_texture("gravel", (1500.0, 1150.0))
        rr = render(Scene(cards, regulated_light(800.0), 1100.0, back, "bench"), rig, supersample=1, seed=1)
        rect = rectification_for(rig, MV_NEAR_MM, MV_FAR_MM)
        lo, hi = disparity_range(rig, MV_NEAR_MM, MV_FAR_MM, rect, width_px=rect.size_px[0])
        _mv.update(rig=rig, image=rr.image, left=255.0 * rr.left, right=255.0 * rr.right,   # radiance -> grey
                   count=int(math.ceil(hi - lo)))
    return _mv


def _mv_dense(params: DenseParams):
    def setup():
        from psvs.dense.build import dense_on_rig
        s = _mv_frame()
        ws = Workspace()
        return lambda: dense_on_rig(s["image"], s["rig"], MV_NEAR_MM, MV_FAR_MM, params=params, workspace=ws)
    return setup


def _mv_sgbm():
    """StereoSGBM 3-way on all cores on the two views rendered alone (1440x1080), numDisparities the dense
    search's count rounded up to a multiple of 16 (sgbm_reference rounds it)."""
    def setup():
        s = _mv_frame()

        def run():
            previous = cv2.getNumThreads()
            cv2.setNumThreads(_cores())
            try:
                sgbm_reference(s["left"], s["right"], s["count"])
            finally:
                cv2.setNumThreads(previous)
        return run
    return setup


MV_DEFAULT = "dense (default mode), 1440x1080 through mv1440, its 400-1200 mm, 2 cores"
MV_FAST = "dense --fast, 1440x1080 through mv1440, its 400-1200 mm, 2 cores"
MV_SGBM = "OpenCV StereoSGBM 3-way on a separate 1440x1080 pair, the same disparity count (to 16), all cores"
RATIOS += [("1440x1080 default mode / StereoSGBM 3-way all cores (target 5)", MV_DEFAULT, MV_SGBM),
           ("1440x1080 --fast / StereoSGBM 3-way all cores (target 1)", MV_FAST, MV_SGBM)]


def cases():
    return [("dense --fast, 640x480, 64 disparities, 2 cores", _dense(FAST), 0.033),
            (DEFAULT_CASE, _dense(DEFAULT), 0.300),
            ("dense (default mode), 640x480, 160 disparities (the rig's range), 2 cores", _dense(DEFAULT, 160), 0.600),
            ("view separation, 640x480", _separate, 0.300),
            (SGBM_ALL, _sgbm(_cores()), float("inf")),
            (SGBM_ONE, _sgbm(1), float("inf")),
            ("psvs live --dense per frame: fast mode over the rig's 400-1200 mm + cloud", _live_dense, float("inf")),
            (MV_SGBM, _mv_sgbm(), float("inf")),
            (MV_DEFAULT, _mv_dense(DEFAULT), float("inf")),
            (MV_FAST, _mv_dense(FAST), float("inf"))]
