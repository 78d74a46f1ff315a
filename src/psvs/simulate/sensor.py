"""The camera's sensor: optical blur, shot and read noise, gain, quantisation (seeded, reproducible)."""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs._validate import check_nonnegative, check_positive
from psvs.imaging.grey import to_grey8


@dataclass(frozen=True)
class Sensor:
    """Sensor model. An irradiance of 1.0 fills ``full_well_e`` electrons; with ``gain`` 1 that is 255.

    blur_sigma_px : Gaussian optical blur (lens PSF), px; 0 = none.
    full_well_e   : electrons at irradiance 1.0 (sets the shot-noise level: SNR = sqrt(electrons)).
    read_noise_e  : Gaussian read noise, electrons RMS.
    gain          : digital gain; grey level = gain * 255 * electrons / full_well_e.
    shot_noise    : Poisson photon noise on or off.
    """

    blur_sigma_px: float = 0.6
    full_well_e: float = 20000.0
    read_noise_e: float = 15.0
    gain: float = 1.0
    shot_noise: bool = True

    def __post_init__(self):
        check_nonnegative(self.blur_sigma_px, "blur_sigma_px", "px")
        check_positive(self.full_well_e, "full_well_e", "electrons")
        check_nonnegative(self.read_noise_e, "read_noise_e", "electrons")
        check_positive(self.gain, "gain")


#: The widest optical blur a sensor may be given, sigma px: a lens blurring more is out of focus beyond use,
#: and the Gaussian kernel (+-4 sigma) costs time in proportion (2 s per 640x480 frame at 1000 px).
MAX_BLUR_PX = 100.0

#: A noiseless, blur-free sensor: quantisation only (for tests and ground-truth comparisons).
IDEAL = Sensor(blur_sigma_px=0.0, read_noise_e=0.0, shot_noise=False)


def blur(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian blur of an (H, W) float image (kernel +-4 sigma, reflected borders)."""
    if sigma_px <= 0:
        return image
    k = 2 * int(np.ceil(4 * sigma_px)) + 1
    return cv2.GaussianBlur(image, (k, k), sigmaX=sigma_px, sigmaY=sigma_px, borderType=cv2.BORDER_REFLECT)


def expose(irradiance: np.ndarray, sensor: Sensor, seed: int | None = 0, bits: int = 8) -> np.ndarray:
    """Turn an (H, W) irradiance image (1.0 = full well) into an 8-bit image (H, W) uint8, or with ``bits``
    10, 12, 14 or 16 a deeper sensor's (H, W) uint16 image of values 0..2**bits - 1 (a Mono12 camera's
    frame: grey level = gain * (2**bits - 1) * electrons / full_well_e, the same noise)."""
    rng = np.random.default_rng(seed)
    e = blur(np.asarray(irradiance, dtype=np.float64), sensor.blur_sigma_px) * sensor.full_well_e
    e = np.clip(e, 0, None)
    if sensor.shot_noise:
        e = rng.poisson(e).astype(np.float64)
    if sensor.read_noise_e > 0:
        e = e + rng.normal(0.0, sensor.read_noise_e, e.shape)
    top = 2 ** bits - 1
    dn = sensor.gain * float(top) * e / sensor.full_well_e
    if bits == 8:
        return to_grey8(dn)
    if bits not in (10, 12, 14, 16):
        raise ValueError(f"bits must be 8, 10, 12, 14 or 16, got {bits!r}")
    return np.clip(np.rint(dn), 0, top).astype(np.uint16)
