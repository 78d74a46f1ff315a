"""The floor under any Numba program's whole call: a fresh process that imports NumPy and Numba and runs one
one-line kernel compiled earlier (loaded from Numba's cache, as psvs's kernels are on every call after a user's
first). Loading the first cached kernel builds Numba's CPU target (its typing and lowering registries, the
BLAS check that imports SciPy's): bench/bench_depth.py times this beside ``psvs disparity --depth`` and the
StereoSGBM script.

    python bench/numba_floor.py
"""
import numba
import numpy as np


@numba.njit(cache=True)
def _add_one(a):
    return a + 1


if __name__ == "__main__":
    _add_one(np.zeros(4))
