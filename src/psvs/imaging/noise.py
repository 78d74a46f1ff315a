"""The sensor's noise read from the image itself: its variance at every brightness.

A camera's noise grows with the light: photon shot noise on a read-out floor, variance
``a + b I`` at grey level I (the Poisson-Gaussian model, Foi et al. 2008). Its level at one brightness is read
from the image's m x m patches of that brightness with their mean removed: the directions of the m² that the
image's own structure spans are few, so the smallest eigenvalues of the patches' covariance hold the noise
alone (Pyatykh, Hesser & Zheng 2013), on a frame full of texture as on a plain one. (Removing each patch's mean
makes one eigenvalue zero; the next one is used, scaled by m²/(m² − 1).) The patches are split into
:data:`BINS` bands of brightness, and ``a``, ``b`` fitted to the bands' variances by least squares weighted by
their patch counts (``b`` = 0 when the fit's slope is negative). Measured on psvs's renders (two exposures'
difference as the truth): 0.74 grey levels against 0.68 on Fig. 5b, 1.38 against 1.37 on a photo wall.

psvs.dense.noise tells texture from it (which pixels of a dense map carry their own); psvs.imaging.edge_noise
asks a pipeline's edges whether they are the scene's or the noise's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

#: px: the patches' side whose covariance gives the noise level.
PATCH_PX = 5
#: brightness bands the patches are split into (fewer on a small image: each needs MIN_BIN_PATCHES).
BINS = 8
MIN_BIN_PATCHES = 200
#: patches read at most (a regular subsample of every patch position: the covariance needs no more).
MAX_PATCHES = 60000


@dataclass(frozen=True)
class NoiseLevel:
    """The sensor noise's variance ``a + b I`` (grey levels squared) at grey level I."""

    a: float
    b: float

    def sigma(self, grey) -> np.ndarray:
        """The noise's standard deviation (grey levels) at grey levels ``grey`` (any shape)."""
        return np.sqrt(np.maximum(self.a + self.b * np.maximum(np.asarray(grey, dtype=np.float64), 0.0), 0.0))


def noise_level(image: np.ndarray, max_patches: int = MAX_PATCHES) -> NoiseLevel:
    """The noise level of ``image`` (H, W) grey, at least :data:`PATCH_PX` px a side (module docstring), read
    from at most ``max_patches`` patches (a regular subsample of every position)."""
    f = np.asarray(image)
    if f.dtype.kind not in "biuf":
        f = f.astype(np.float64)
    if f.ndim != 2 or min(f.shape) < PATCH_PX:
        raise ValueError(f"the noise level needs a grey image of at least {PATCH_PX} px a side, got shape {f.shape}")
    m = PATCH_PX
    positions = (f.shape[0] - m + 1) * (f.shape[1] - m + 1)
    stride = max(1, math.ceil(math.sqrt(positions / max_patches)))
    # the patches read, as float64 (not a float64 copy of the whole frame first)
    patches = sliding_window_view(f, (m, m))[::stride, ::stride].reshape(-1, m * m).astype(np.float64)
    mean = patches.mean(axis=1)
    patches = patches - mean[:, None]
    bins = max(1, min(BINS, len(patches) // MIN_BIN_PATCHES))
    order = np.argsort(mean, kind="stable")
    grey, var, weight = [], [], []
    for part in np.array_split(order, bins):
        # the covariance by OpenCV, not BLAS: OpenBLAS's threads on a 7500 x 25 product wait for each other, and on
        # a loaded machine the call took 1.4 s instead of 20 ms (bench/bench_depth.py's library call)
        p = np.ascontiguousarray(patches[part])
        ev = np.linalg.eigvalsh(cv2.mulTransposed(p, True) / len(p))
        grey.append(float(mean[part].mean()))
        var.append(float(ev[1]) * m * m / (m * m - 1))
        weight.append(len(part))
    grey_a, var_a, w = np.asarray(grey), np.asarray(var), np.sqrt(np.asarray(weight, dtype=np.float64))
    if bins >= 2 and np.ptp(grey_a) > 1e-9:
        (a, b), *_ = np.linalg.lstsq(np.column_stack([w, w * grey_a]), w * var_a, rcond=None)
        if b >= 0:
            return NoiseLevel(max(float(a), 0.0), float(b))
    return NoiseLevel(float(np.average(var_a, weights=w * w)), 0.0)
