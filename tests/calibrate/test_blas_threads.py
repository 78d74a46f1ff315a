"""A calibration gives the same numbers whatever the BLAS library's threads: ``psvs calibrate`` holds NumPy's and
SciPy's OpenBLAS to one thread (psvs._threads.one_blas_thread), so that a Monte-Carlo sample on a cluster's
worker is what the same build gives alone on any machine. On 1 and 2 OpenBLAS threads a study sample's
3-D RMS differed in the seventh digit before."""
from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from psvs._threads import one_blas_thread
from psvs.calibrate.folder import calibrate_folder
from psvs.io.params import load_rig
from psvs.study.build import apply_deviations, draw_deviations
from psvs.study.sample import render_card_folder
from psvs.study.tolerances import tolerances_from_dict

#: A small study's build and procedure (tests/study/test_montecarlo.py's): 4 card views at 1x1.
SMALL = {"tolerances": {"mirror_tilt_deg": {"uniform": 0.2}, "mirror_shift_mm": {"uniform": 0.5}},
         "calibration": {"views": 4, "supersample": 1}}


def _blas_threads() -> set:
    return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}


def test_one_blas_thread_holds_every_blas_library_and_restores_the_setting():
    with threadpool_limits(limits=2, user_api="blas"):
        assert _blas_threads() == {2}
        with one_blas_thread():
            infos = [lib for lib in threadpool_info() if lib["user_api"] == "blas"]
            assert any("scipy" in lib["filepath"] for lib in infos)     # SciPy's own OpenBLAS is loaded and held
            assert {lib["num_threads"] for lib in infos} == {1}
        assert _blas_threads() == {2}


@pytest.mark.slow
@pytest.mark.parametrize("index", [0, 3])
def test_a_calibration_is_the_same_on_one_and_on_two_blas_threads(tmp_path, index):
    nominal = load_rig("default")
    tol = tolerances_from_dict(SMALL)
    build = apply_deviations(nominal, draw_deviations(tol, 11, index))
    render_card_folder(build, tol.procedure, 100 + index, tmp_path)
    results = []
    for threads in (1, 2):
        with threadpool_limits(limits=threads, user_api="blas"):
            results.append(calibrate_folder(tmp_path, nominal).bundle)
    one, two = results
    assert one.values == two.values                       # bit for bit, every rig parameter
    assert one.rms_px == two.rms_px
    assert np.array_equal(one.covariance, two.covariance)
