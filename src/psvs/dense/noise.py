"""How much of an image's fine detail is its sensor's noise, read from the image itself, and which pixels carry
texture beyond it.

A pixel of a flat surface (a plain backdrop, the white top of an object) has nothing of its own to match: the
aggregation gives it a neighbour's disparity, and a surface beside it that the echo supports carries it into
the trusted answers (on Fig. 5b 41 % of the trusted pixels were such backdrop, docs/dense.md). A dense answer
is therefore trusted only where the pixel's own window carries texture beyond what the sensor's noise gives
there (:mod:`psvs.dense.trust`); for that the noise must be known, at every brightness, on any camera.

**The noise level.** A camera's noise grows with the light: photon shot noise on a read-out floor, variance
``a + b I`` at grey level I (the Poisson-Gaussian model, Foi et al. 2008). Its level at one brightness is read
from the image's m x m patches of that brightness with their mean removed: the directions of the m² that the
image's own structure spans are few, so the smallest eigenvalues of the patches' covariance hold the noise
alone (Pyatykh, Hesser & Zheng 2013), on a frame full of texture as on a plain one. (Removing each patch's mean
makes one eigenvalue zero; the next one is used, scaled by m²/(m² − 1).) The patches are split into
:data:`BINS` bands of brightness, and ``a``, ``b`` fitted to the bands' variances by least squares weighted by
their patch counts (``b`` = 0 when the fit's slope is negative). Measured on psvs's renders (two exposures'
difference as the truth): 0.74 grey levels against 0.68 on Fig. 5b, 1.38 against 1.37 on a photo wall.

**The texture test.** In each of :data:`SCALES` (the image minus its blur of 1 px over 3 x 3 windows, the
blur of 1 px minus the blur of 2 px over 5 x 5: the smallest windows that measure each band), the band's RMS
over the window about each pixel: on white noise of unit variance that RMS has one distribution, fixed by the
filters, whose 1 − :data:`FALSE_ALARM` quantile K is read from seeded noise (:data:`QUANTILES`). A pixel is
textured when, in one scale, its window's RMS exceeds K times the noise level at the window's mean grey level:
a flat window passes one scale with probability :data:`FALSE_ALARM` (0.35-0.4 % of a flat frame's pixels pass
either, tests/dense/test_noise.py). Where the noise is
spatially correlated (a demosaiced colour sensor, a JPEG, a build's rectified grid, resampled), the smallest
eigenvalues see less of it, the level is read low and more pixels pass: the test errs toward keeping texture,
never toward refusing it.
"""
from __future__ import annotations

import functools
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
#: The texture's bands and windows, px: (sigma, window side); band sigma is the image minus its Gaussian blur
#: of sigma for sigma <= 1, else blur(sigma / 2) minus blur(sigma). A pixel is textured in any of them.
SCALES = ((1.0, 3), (2.0, 5))
#: the share of a flat window's pixels taken for texture.
FALSE_ALARM = 0.001


@dataclass(frozen=True)
class NoiseLevel:
    """The sensor noise's variance ``a + b I`` (grey levels squared) at grey level I."""

    a: float
    b: float

    def sigma(self, grey) -> np.ndarray:
        """The noise's standard deviation (grey levels) at grey levels ``grey`` (any shape)."""
        return np.sqrt(np.maximum(self.a + self.b * np.maximum(np.asarray(grey, dtype=np.float64), 0.0), 0.0))


def noise_level(image: np.ndarray) -> NoiseLevel:
    """The noise level of ``image`` (H, W) grey, at least :data:`PATCH_PX` px a side (module docstring)."""
    f = np.asarray(image, dtype=np.float64)
    if f.ndim != 2 or min(f.shape) < PATCH_PX:
        raise ValueError(f"the noise level needs a grey image of at least {PATCH_PX} px a side, got shape {f.shape}")
    m = PATCH_PX
    positions = (f.shape[0] - m + 1) * (f.shape[1] - m + 1)
    stride = max(1, math.ceil(math.sqrt(positions / MAX_PATCHES)))
    patches = sliding_window_view(f, (m, m))[::stride, ::stride].reshape(-1, m * m)
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


def _band(image: np.ndarray, sigma: float, blurs: dict | None = None) -> np.ndarray:
    """The texture band of ``sigma`` (:data:`SCALES`) of ``image`` float32 (H, W); ``blurs``: the image's blurs
    by sigma, shared between bands (filled as they are made)."""
    blurs = {} if blurs is None else blurs

    def blur(s: float) -> np.ndarray:
        if s not in blurs:
            blurs[s] = cv2.GaussianBlur(image, (0, 0), s, borderType=cv2.BORDER_REFLECT)
        return blurs[s]
    return cv2.subtract(image if sigma <= 1.0 else blur(sigma / 2), blur(sigma))


def _window_power(band: np.ndarray, window: int) -> np.ndarray:
    """The mean square of ``band`` over each ``window``-square window (>= 0)."""
    return np.maximum(cv2.boxFilter(cv2.multiply(band, band), -1, (window, window), borderType=cv2.BORDER_REFLECT),
                      0.0)


#: :func:`noise_quantile` of the :data:`SCALES` at :data:`FALSE_ALARM`, as :func:`simulated_quantile` gives
#: them (a process need not spend 0.1 s on the draw: tests/dense/test_noise.py checks them against it).
QUANTILES = {(1.0, 3, 0.001): 1.5762766599655151, (2.0, 5, 0.001): 0.34979531168937683}


def noise_quantile(sigma: float, window: int, false_alarm: float = FALSE_ALARM) -> float:
    """K: the window RMS of the texture band (``sigma``, ``window``: one of :data:`SCALES`) that white noise of
    unit variance exceeds with probability ``false_alarm`` (:data:`QUANTILES`, else :func:`simulated_quantile`)."""
    known = QUANTILES.get((float(sigma), int(window), float(false_alarm)))
    return known if known is not None else simulated_quantile(sigma, window, false_alarm)


@functools.lru_cache(maxsize=16)
def simulated_quantile(sigma: float, window: int, false_alarm: float = FALSE_ALARM) -> float:
    """:func:`noise_quantile` read from 1024 x 1024 px of seeded white noise (the border's windows left out)."""
    z = np.random.default_rng(20261202).standard_normal((1024, 1024)).astype(np.float32)
    r = np.sqrt(_window_power(_band(z, sigma), window))[16:-16, 16:-16]
    return float(np.quantile(r, 1.0 - false_alarm))


def textured_pixels(image: np.ndarray, noise: NoiseLevel | None = None,
                    false_alarm: float = FALSE_ALARM) -> np.ndarray:
    """bool (H, W): the pixels of ``image`` (H, W) grey whose window carries texture beyond the sensor's noise
    in one of the :data:`SCALES` (module docstring), each at ``false_alarm``; ``noise``: the image's level
    (:func:`noise_level` of it when None)."""
    f = np.ascontiguousarray(image, dtype=np.float32)
    noise = noise_level(f) if noise is None else noise
    # the filters' own rounding (float32) is no texture: a floor of 1e-4 of the image's largest value
    floor = (1e-4 * max(float(np.abs(f).max()) if f.size else 0.0, 1e-12)) ** 2
    out = np.zeros(f.shape, bool)
    blurs: dict = {}
    for sigma, window in SCALES:
        k2 = noise_quantile(sigma, window, false_alarm) ** 2
        mean = cv2.boxFilter(f, -1, (window, window), borderType=cv2.BORDER_REFLECT)
        level = np.maximum(np.float32(noise.a) + np.float32(noise.b) * np.maximum(mean, 0.0), np.float32(floor))
        out |= _window_power(_band(f, sigma, blurs), window) > np.float32(k2) * level
    return out
