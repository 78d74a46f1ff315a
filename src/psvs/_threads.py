"""How many threads psvs's own pools (the renderer's, Embree's) may use in this thread: every core by default,
or the share a task runner gives each task (:func:`thread_share`), so that two tasks on two cores do not each
start two threads. Results never depend on it, only the time.

The BLAS library's pool (OpenBLAS, under NumPy and SciPy) is another matter: a long dot product or norm on
several threads sums in another order, and a calibration's last digits then depend on the thread count.
:func:`one_blas_thread` holds it to one thread where psvs promises the same numbers on any core count."""
from __future__ import annotations

import contextlib
import os
import threading

_local = threading.local()
#: the machine's cores, read once (os.cpu_count reads the system on every call; a projection asks twice)
_CORES = os.cpu_count() or 1


def pool_size(limit: int | None = None) -> int:
    """Threads for a pool started in this thread: the share set by :func:`thread_share`, else the cores,
    at most ``limit``."""
    n = getattr(_local, "share", None) or _CORES
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


_blas_lock = threading.Lock()
_blas_holders = 0
_blas_limiter = None


@contextlib.contextmanager
def one_blas_thread():
    """Within the block the BLAS libraries loaded (NumPy's, SciPy's, loaded first, and OpenCV's) run on one
    thread, so that their results do not depend on the number of threads; the process's setting is restored
    when the last thread inside such a block leaves it (the setting is the process's: other threads' BLAS calls
    run on one thread meanwhile). Also a decorator: ``@one_blas_thread()``.

    A calibration's least squares takes norms and dot products of vectors of thousands of residuals, which
    OpenBLAS splits among its threads: on 1 and 2 threads a Monte-Carlo sample's 3-D RMS differed in the
    seventh digit (tests/calibrate/test_blas_threads.py). One thread removes the dependence on the thread
    count only: another CPU type (OpenBLAS picks its kernels by CPU) or library version may still change the
    last digits."""
    global _blas_holders, _blas_limiter
    with _blas_lock:
        if _blas_holders == 0:
            import scipy.linalg  # noqa: F401  (loads SciPy's own OpenBLAS, so that the limit reaches it)
            from threadpoolctl import threadpool_limits
            _release_blas_control()
            _blas_limiter = threadpool_limits(limits=1, user_api="blas")
            _release_blas_control()
        _blas_holders += 1
    try:
        yield
    finally:
        with _blas_lock:
            _blas_holders -= 1
            if _blas_holders == 0:
                _release_blas_control()
                _blas_limiter.restore_original_limits()
                _release_blas_control()
                _blas_limiter = None


def _release_blas_control() -> None:
    """threadpoolctl (3.8 on) lets one Python thread at a time set OpenBLAS's process-wide pool, the first to
    set it, and silently ignores the others: release it, so that the thread that sets it next (the last to
    leave a block above, or the caller's own) is heard."""
    import threadpoolctl
    clear = getattr(getattr(threadpoolctl, "OpenBLASController", None), "clear_controlling_thread", None)
    if clear is not None:
        clear(force=True)
