"""How many threads psvs's own pools (the renderer's, Embree's) may use in this thread: every core by default,
or the share a task runner gives each task (:func:`thread_share`), so that two tasks on two cores do not each
start two threads. Results never depend on it, only the time."""
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
