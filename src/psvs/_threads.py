"""How many threads psvs's own pools (the renderer's, Embree's) may use in this thread: every core by default,
or the share a task runner gives each task (:func:`thread_share`), so that two tasks on two cores do not each
start two threads. Results never depend on it, only the time.

The BLAS library's pool (OpenBLAS, under NumPy and SciPy) is another matter: a long dot product or norm on
several threads sums in another order, and a calibration's last digits then depend on the machine's cores.
:func:`one_blas_thread` holds it to one thread where psvs promises the same numbers everywhere."""
from __future__ import annotations

import contextlib
import os
import threading

_local = threading.local()


def pool_size(limit: int | None = None) -> int:
    """Threads for a pool started in this thread: the share set by :func:`thread_share`, else the cores,
    at most ``limit``."""
    n = getattr(_local, "share", None) or os.cpu_count() or 1
    return max(1, min(n, limit) if limit else n)


@contextlib.contextmanager
def thread_share(threads: int | None):
    """Within the block, pools started in this thread use at most ``threads`` threads (None: no change)."""
    old = getattr(_local, "share", None)
    if threads is not None:
        _local.share = max(1, int(threads))
    try:
        yield
    finally:
        _local.share = old


@contextlib.contextmanager
def one_blas_thread():
    """Within the block NumPy's and SciPy's BLAS libraries (every one loaded, SciPy's loaded first) run on one
    thread, so that their results do not depend on the cores; the process's setting is restored after.

    A calibration's least squares takes norms and dot products of vectors of thousands of residuals, which
    OpenBLAS splits among its threads: on 1 and 2 threads a Monte-Carlo sample's 3-D RMS differed in the
    seventh digit (tests/calibrate/test_blas_threads.py)."""
    import scipy.linalg  # noqa: F401  (loads SciPy's own OpenBLAS, so that the limit reaches it)
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=1, user_api="blas"):
        yield
