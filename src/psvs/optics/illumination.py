"""The lens's relative illumination (vignetting of the real camera): how much less light reaches the sensor
away from the axis.

A lens datasheet plots relative illumination RI against image height h (mm on the sensor, 100 % on the
axis): natural fall-off (cos^4 of the chief ray's angle in image space), the pupil's foreshortening and the
barrel's own vignetting together. psvs fits it by an even polynomial in the normalised image radius
rho = h / f, the radius OpenCV's lens model uses (of the *distorted* image point, where the light lands):

    RI(rho) = 1 + a2 rho^2 + a4 rho^4            (camera.relative_illumination = [a2, a4])

rho depends only on the lens (not on the sensor's size or a sensor window), so the same two terms hold
for a camera read out through a window. cos^4 alone is 1 / (1 + rho^2)^2 ~ 1 - 2 rho^2 + 3 rho^4 for a
distortion-free lens. The default (0, 0) is a flat field. RI multiplies the complex image: both views
pass the same lens.
"""
from __future__ import annotations

import functools

import cv2
import numpy as np

from psvs.optics.rig import Camera


def relative_illumination(uv_px, camera: Camera) -> np.ndarray:
    """RI (N,) of pixels ``uv_px`` (N, 2), px: 1 on the axis (the principal point), < 1 away from it.

    Examples
    --------
    >>> cam = Camera(focal_length_mm=8.0, pixel_pitch_mm=(0.01, 0.01), image_size_px=(1601, 1201),
    ...              principal_point_px=(800.0, 600.0), relative_illumination=(-1.0, -2.0))
    >>> relative_illumination([[800.0, 600.0], [1200.0, 600.0]], cam).round(12)   # h = 4 mm: rho = 0.5
    array([1.   , 0.625])
    """
    uv = np.asarray(uv_px, dtype=np.float64).reshape(-1, 2)
    xy = (uv - np.asarray(camera.principal_point_px)) * np.asarray(camera.pixel_pitch_mm)
    rho2 = np.einsum("ij,ij->i", xy, xy) / camera.focal_length_mm ** 2
    return ri_of_rho2(rho2, camera.relative_illumination)


def ri_of_rho2(rho2: np.ndarray, terms: tuple[float, float]) -> np.ndarray:
    """RI = 1 + a2 rho^2 + a4 rho^4 of squared normalised radii ``rho2`` (any shape)."""
    a2, a4 = terms
    return 1.0 + rho2 * (a2 + rho2 * a4)


def illumination_map(camera: Camera) -> np.ndarray:
    """RI (H, W) at every pixel centre of the camera (ones for a flat field)."""
    w, h = camera.image_size_px
    if not camera.vignetted:
        return np.ones((h, w))
    (cx, cy), (px, py) = camera.principal_point_px, camera.pixel_pitch_mm
    x2 = (((np.arange(w) - cx) * px) ** 2)[None, :]
    y2 = (((np.arange(h) - cy) * py) ** 2)[:, None]
    return ri_of_rho2((x2 + y2) / camera.focal_length_mm ** 2, camera.relative_illumination)


def corner_rho2(camera: Camera) -> float:
    """The largest rho^2 on the sensor: at the outer edge of its corner pixel farthest from the axis."""
    w, h = camera.image_size_px
    (cx, cy), (px, py) = camera.principal_point_px, camera.pixel_pitch_mm
    dx = max(cx + 0.5, w - 0.5 - cx) * px
    dy = max(cy + 0.5, h - 0.5 - cy) * py
    return (dx * dx + dy * dy) / camera.focal_length_mm ** 2


def ri_range(camera: Camera, samples: int = 513) -> tuple[float, float]:
    """(min, max) of RI over the sensor (rho from 0 to its farthest corner), sampled densely in rho^2 (a
    quadratic in rho^2, so its extremes are at the ends or the vertex, which is added)."""
    a2, a4 = camera.relative_illumination
    top = corner_rho2(camera)
    q = np.linspace(0.0, top, samples)
    if a4 != 0.0 and 0.0 < -a2 / (2 * a4) < top:
        q = np.append(q, -a2 / (2 * a4))
    ri = ri_of_rho2(q, (a2, a4))
    return float(ri.min()), float(ri.max())


@functools.lru_cache(maxsize=8)
def _gain(camera: Camera) -> np.ndarray:
    """1 / RI (H, W) float32, read-only: the flat-field gain of a camera (cached: a live loop asks every frame)."""
    g = (1.0 / illumination_map(camera)).astype(np.float32)
    g.setflags(write=False)
    return g


def flat_field(grey: np.ndarray, camera: Camera) -> np.ndarray:
    """The (H, W) uint8 image as a flat lens would have recorded it: each pixel divided by the lens's
    relative illumination there (the shading correction of a machine-vision camera), rounded and saturated
    at 255. The image itself when the camera's field is flat. Fixed grey-level thresholds (the paper's 92)
    and the sub-pixel edge model then see the same contrast in the corners as on the axis.

    Examples
    --------
    >>> cam = Camera(focal_length_mm=1.0, pixel_pitch_mm=(0.5, 0.5), image_size_px=(3, 1),
    ...              principal_point_px=(1.0, 0.0), relative_illumination=(-0.5, 0.0))
    >>> flat_field(np.array([[75, 100, 75]], np.uint8), cam)      # RI = 0.875, 1, 0.875
    array([[ 86, 100,  86]], dtype=uint8)
    """
    if not camera.vignetted:
        return grey
    gain = _gain(camera)
    if grey.shape != gain.shape:
        raise ValueError(f"image is {grey.shape[1]}x{grey.shape[0]} px but the camera is "
                         f"{gain.shape[1]}x{gain.shape[0]} px")
    return cv2.multiply(grey, gain, dtype=cv2.CV_8U)
