"""Whether a pipeline's edges are the scene's or the sensor's noise.

An edge detector marks where the grey image steps. A scene's edge steps the same way in every exposure; the
sensor's noise steps anew in each. A pipeline whose thresholds sit near the noise's own gradients (a Canny of
2 and 6 grey levels, a low binarisation over a flat region) marks the noise too: on a frame of Fig. 5a a fifth
of the pixels, in chains that cross the rows everywhere, and the automatic matcher paired them with each other
at lags where no surface stands (an adversarial trial: 56-90 % of the paired pixels 25-37 % off in depth, exit
0, on every noise seed; the chance test reads its null at lags whose overlap of the image is smaller, so it did
not see them).

The test asks the frame itself. Its noise level is read from it (:func:`psvs.imaging.noise.noise_level`); two
copies of the frame each get a fresh draw of that noise (Gaussian, its variance at each pixel's brightness), and
the pipeline runs on both. A scene's edge pixel comes back in the other copy, at the same pixel, most of the
time; a noise edge's only as often as the other copy's noise happens to mark that pixel. The share of the first
copy's edge pixels that the second copy marks too is the edges' *stability*. Both copies carry the frame's own
noise as well as their draw, so a noise edge comes back more often than chance alone would bring it (its copies'
noise correlates at 1/2): measured (seed 0), Canny 2/6, 0/0 or a median and 0/0 on Fig. 5a, Fig. 5b and a
1440 x 1080 build's Fig. 5a: 0.33-0.44, and 0.44-0.47 on twelve drawn scenes of blurred discs (tests); with a
median and 5/15, 0.38-0.43 on Fig. 5a (14 % of its paired pixels 3-5 % off) and 0.57 on Fig. 5b. The paper's
pipeline and Canny at 10/30 to 50/150 on the same frames, the textured scene and Middlebury's Motorcycle
superimposed: 0.72-1.00, and 0.74-0.99 on the drawn scenes. Below :data:`MIN_STABLE_SHARE`, between the two,
the edges are more noise than scene, and nothing found on them is an answer. (On a frame full of fine texture
even a Canny at 0/0 marks mostly the texture, 0.67-0.77 on the textured scene and Motorcycle: those edges are
the scene's, and whether they can be paired is the matcher's question.) The test costs 3 ms on a 640 x 480
frame, 12 ms on 1440 x 1080 (the noise level from 6000 patches, the draws made once per frame size).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from psvs.imaging.noise import NoiseLevel, noise_level

#: The least share of a pipeline's edge pixels that must come back when the frame's noise is drawn anew, for
#: its edges to be taken for the scene's (module docstring).
MIN_STABLE_SHARE = 0.6
#: The patches the frame's noise level is read from here (a tenth of what the dense engine's texture test
#: reads: a level within a few per cent is plenty for this test, at a tenth of the time).
NOISE_PATCHES = 6000


@dataclass(frozen=True)
class EdgeStability:
    """How a pipeline's edges on one frame stood a fresh draw of its noise: ``edge_pixels`` the edges of the
    first noisy copy, ``stable_share`` the share of them the second copy marks too, ``sigma_grey`` the frame's
    noise (grey levels, at its mean brightness)."""

    edge_pixels: int
    stable_share: float
    sigma_grey: float

    @property
    def noise(self) -> bool:
        """Whether the edges are more the noise's than the scene's (:data:`MIN_STABLE_SHARE`)."""
        return self.edge_pixels > 0 and self.stable_share < MIN_STABLE_SHARE

    def describe(self) -> str:
        """The figures in words, for a refusal."""
        return (f"the pipeline's edges are mostly the sensor's noise: with the frame's noise ({self.sigma_grey:.2f} "
                f"grey levels) drawn anew twice, {100 * self.stable_share:.0f} % of the first draw's "
                f"{self.edge_pixels} edge pixels come back in the second, where a scene's edges mostly do "
                f"({100 * MIN_STABLE_SHARE:.0f} % asked): raise the pipeline's thresholds, or smooth before its edge "
                "detector")


@functools.lru_cache(maxsize=4)
def _white(shape: tuple[int, int], seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Two draws of unit white Gaussian noise (H, W) float32 of ``seed``, made once per shape (read-only): one,
    and the same rolled by half the frame each way (no pixel meets its own value or a neighbour's)."""
    z = np.random.default_rng(seed).standard_normal(shape, dtype=np.float32)
    rolled = np.roll(z, (shape[0] // 2, shape[1] // 2), axis=(0, 1))
    for a in (z, rolled):
        a.setflags(write=False)
    return z, rolled


def edge_stability(grey: np.ndarray, pipeline, noise: NoiseLevel | None = None, seed: int = 0) -> EdgeStability:
    """The stability of ``pipeline``'s edges (a :class:`psvs.imaging.pipeline.Pipeline`) on the frame ``grey``
    (H, W) uint8 under fresh draws of its noise (module docstring); ``noise`` its level
    (:func:`~psvs.imaging.noise.noise_level` of it when None); ``seed`` the draws' (the same answer every time)."""
    f = np.asarray(grey, dtype=np.float32)
    level = noise_level(f, NOISE_PATCHES) if noise is None else noise
    # sigma at each pixel's brightness, float32 (a constant when the noise does not grow with the light)
    sigma = (np.float32(np.sqrt(max(level.a, 0.0))) if level.b == 0 else
             cv2.sqrt(cv2.max(cv2.add(cv2.multiply(cv2.max(f, 0.0), float(level.b)), float(level.a)), 0.0)))
    maps = []
    for draw in _white(f.shape, seed):
        # the copy rounded and saturated to 8 bits as a camera's: one OpenCV pass
        copy = cv2.add(f, cv2.multiply(draw, sigma) if np.ndim(sigma) else draw * sigma, dtype=cv2.CV_8U)
        maps.append(np.asarray(pipeline.run(copy)) > 0)
    first, second = maps
    n = int(cv2.countNonZero(first.view(np.uint8)))
    share = float(cv2.countNonZero((first & second).view(np.uint8)) / n) if n else 1.0
    return EdgeStability(n, share, float(level.sigma(cv2.mean(f)[0])))
