"""How much of an image's fine detail is its sensor's noise, read from the image itself, and which pixels carry
texture beyond it.

A pixel of a flat surface (a plain backdrop, the white top of an object) has nothing of its own to match: the
aggregation gives it a neighbour's disparity, and a surface beside it that the echo supports carries it into
the trusted answers (on Fig. 5b 41 % of the trusted pixels were such backdrop, docs/dense.md). A dense answer
is therefore trusted only where the pixel's own window carries texture beyond what the sensor's noise gives
there (:mod:`psvs.dense.trust`); for that the noise must be known, at every brightness, on any camera.

**The noise level** (:func:`psvs.imaging.noise.noise_level`): the variance ``a + b I`` of the sensor's noise
at grey level I, read from the image's own patches.

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

import cv2
import numba as nb
import numpy as np

from psvs.imaging import NoiseLevel, noise_level

#: The texture's bands and windows, px: (sigma, window side); band sigma is the image minus its Gaussian blur
#: of sigma for sigma <= 1, else blur(sigma / 2) minus blur(sigma). A pixel is textured in any of them.
SCALES = ((1.0, 3), (2.0, 5))
#: the share of a flat window's pixels taken for texture.
FALSE_ALARM = 0.001


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
    """The mean square of ``band`` over each ``window``-square window (the box filter's rounding may leave it a
    hair below 0: its readers clamp it)."""
    return cv2.boxFilter(cv2.multiply(band, band), -1, (window, window), borderType=cv2.BORDER_REFLECT)


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
    r = np.sqrt(np.maximum(_window_power(_band(z, sigma), window), 0.0))[16:-16, 16:-16]
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
        band = _band(f, sigma, blurs)
        _beyond_noise(mean, _window_power(band, window), np.float32(noise.a), np.float32(noise.b),
                      np.float32(floor), np.float32(k2), out)
    return out


@nb.njit(cache=True, parallel=True)
def _beyond_noise(mean, power, a, b, floor, k2, out):  # pragma: no cover - compiled
    """out |= max(power, 0) > k2 · max(a + b · max(mean, 0), floor), all float32 (H, W) and scalars: one pass,
    in float32 as the NumPy expression was (the same pixels), not eight full-size temporaries."""
    zero = np.float32(0.0)
    for y in nb.prange(mean.shape[0]):
        for x in range(mean.shape[1]):
            level = max(a + b * max(mean[y, x], zero), floor)
            if max(power[y, x], zero) > k2 * level:
                out[y, x] = True
