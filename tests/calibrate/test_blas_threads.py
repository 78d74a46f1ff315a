"""A calibration gives the same numbers whatever the BLAS library's thread count: the bundle adjustment, ``psvs
calibrate``'s folder calibration and the hand-eye refinement hold NumPy's and SciPy's OpenBLAS to one thread
(psvs._threads.one_blas_thread), so that a Monte-Carlo sample on a cluster's worker is what the same build
gives alone. On 1 and 2 OpenBLAS threads a study sample's 3-D RMS differed in the seventh digit before."""
from __future__ import annotations

import threading
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_info, threadpool_limits

from psvs._threads import one_blas_thread
from psvs.calibrate.folder import calibrate_folder
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.study.build import apply_deviations, draw_deviations
from psvs.study.sample import render_card_folder
from psvs.study.tolerances import tolerances_from_dict
from psvs.transforms import concat, invert_transform, transform_from

#: A small study's build and procedure (tests/study/test_montecarlo.py's): 4 card views at 1x1.
SMALL = {"tolerances": {"mirror_tilt_deg": {"uniform": 0.2}, "mirror_shift_mm": {"uniform": 0.5}},
         "calibration": {"views": 4, "supersample": 1}}


def _blas_threads() -> set:
    return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}


def _recording(monkeypatch, module):
    """Replace ``module.least_squares`` by one that records the BLAS thread counts it ran with."""
    seen, real = [], module.least_squares

    def least_squares(*args, **kwargs):
        seen.append(_blas_threads())
        return real(*args, **kwargs)
    monkeypatch.setattr(module, "least_squares", least_squares)
    return seen


def test_one_blas_thread_holds_every_blas_library_and_restores_the_setting():
    with threadpool_limits(limits=2, user_api="blas"):
        assert _blas_threads() == {2}
        with one_blas_thread():
            infos = [lib for lib in threadpool_info() if lib["user_api"] == "blas"]
            assert any("scipy.libs" in lib["filepath"] for lib in infos)     # SciPy's own OpenBLAS, held too
            assert {lib["num_threads"] for lib in infos} == {1}
        assert _blas_threads() == {2}


def test_two_threads_inside_hold_it_until_the_last_one_leaves():
    """The setting is the process's: a thread leaving its block while another is still inside must not give
    the other its threads back."""
    a_in, b_in, a_out, b_done = (threading.Event() for _ in range(4))
    seen = {}

    def a():
        with one_blas_thread():
            a_in.set()
            b_in.wait(5)
        a_out.set()

    def b():
        a_in.wait(5)
        with one_blas_thread():
            b_in.set()
            a_out.wait(5)
            seen["b after a left"] = _blas_threads()
        b_done.set()

    with threadpool_limits(limits=2, user_api="blas"):
        threads = [threading.Thread(target=f) for f in (a, b)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(10)
        assert b_done.is_set()
        assert seen["b after a left"] == {1}
        assert _blas_threads() == {2}


def test_the_hand_eye_refinement_runs_on_one_blas_thread(monkeypatch):
    """refine_hand_eye's solver sees one BLAS thread; the setting is back after (a synthetic 4-pose set)."""
    import psvs.robot.handeye_refine as refine
    rig = load_rig("default")
    model = np.array([[x, y, 0.0] for x in range(0, 100, 20) for y in range(0, 80, 20)], dtype=np.float64)
    target2base = transform_from(np.eye(3), [-50.0, -40.0, 600.0])
    flanges = [transform_from(Rotation.from_rotvec(np.radians(r)).as_matrix(), t)
               for r, t in (([0, 0, 0], [0, 0, 0]), ([3, 0, 0], [10, 0, 5]), ([0, 4, 0], [0, -8, 0]),
                            ([2, -2, 5], [5, 5, -10]))]
    fits = []
    for F in flanges:
        t2c = concat(target2base, invert_transform(F))          # cam2flange = identity
        pts = model @ t2c[:3, :3].T + t2c[:3, 3]
        (uv_l, ok_l), (uv_r, ok_r) = (project_points(pts, rig, v) for v in ("left", "right"))
        assert ok_l.all() and ok_r.all()
        fits.append(SimpleNamespace(left_px=uv_l, right_px=uv_r, target2cam=t2c))
    seen = _recording(monkeypatch, refine)
    with threadpool_limits(limits=2, user_api="blas"):
        X, _, rms = refine.refine_hand_eye(flanges, fits, model, rig, np.eye(4))
        assert _blas_threads() == {2}
    assert seen == [{1}]
    assert rms < 1e-6 and np.allclose(X, np.eye(4), atol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("index", [0, 3])
def test_a_calibration_is_the_same_on_one_and_on_two_blas_threads(tmp_path, monkeypatch, index):
    import psvs.calibrate.bundle as bundle
    nominal = load_rig("default")
    tol = tolerances_from_dict(SMALL)
    build = apply_deviations(nominal, draw_deviations(tol, 11, index))
    render_card_folder(build, tol.procedure, 100 + index, tmp_path)
    seen = _recording(monkeypatch, bundle)
    results = []
    for threads in (1, 2):
        with threadpool_limits(limits=threads, user_api="blas"):
            results.append(calibrate_folder(tmp_path, nominal).bundle)
    assert seen and all(s == {1} for s in seen)          # every solve of the bundle adjustment on one thread
    one, two = results
    assert one.values == two.values                       # bit for bit, every rig parameter
    assert one.rms_px == two.rms_px
    assert np.array_equal(one.covariance, two.covariance)
