"""Task functions for the cluster tests, in a module of their own so that the workers import them by name."""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np


def sample(key: int, seed: int = 7) -> dict:
    """A pure function of its key, like a Monte-Carlo sample seeded from (seed, index): a few draws of a
    generator seeded by both, and a summary of them."""
    rng = np.random.default_rng([seed, key])
    x = rng.normal(size=1000)
    return {"mean": float(x.mean()), "max": float(x.max()), "n_pos": int((x > 0).sum()), "tag": f"s{key}",
            "ok": bool(x.mean() > 0)}


def counted(calls_dir: str, delay_s: float, key: int) -> dict:
    """:func:`sample` of ``key``, after ``delay_s``, leaving a file in ``calls_dir`` per call (so a test can
    count what ran) and saying which worker process ran it."""
    Path(calls_dir, f"{key}-{time.time_ns()}").touch()
    time.sleep(delay_s)
    return {**sample(key), "pid": os.getpid()}


def fails_on(bad: int, key: int) -> dict:
    if key == bad:
        raise RuntimeError(f"sample {key} cannot be drawn\nsecond line")
    return sample(key)


def not_a_row(key: int):
    return {"array": np.zeros(3)}


def numba_threads(key: int) -> dict:
    import numba
    return {"threads": numba.get_num_threads()}


def environ(key: int) -> dict:
    """The worker's settings of the thread pools that Dask's default environment would set."""
    names = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS", "MALLOC_TRIM_THRESHOLD_")
    return {n: os.environ.get(n, "unset") for n in names}
