"""The sensor's noise read from the image itself and the pixels with texture of their own (psvs.dense.noise):
planted Poisson-Gaussian noise on plain and photographed images, the texture test's false alarm on flat
frames, and the halo of a plain backdrop beside textured objects no longer trusted (psvs.dense.trust)."""
import cv2
import numpy as np
import pytest
from skimage import data

from psvs.dense.noise import FALSE_ALARM, SCALES, noise_quantile, simulated_quantile, textured_pixels
from psvs.imaging import NoiseLevel, noise_level


def _noisy(clean: np.ndarray, a: float, b: float, seed: int) -> np.ndarray:
    """``clean`` (grey levels) with Poisson-Gaussian noise of variance a + b * clean, rounded to 8 bits."""
    rng = np.random.default_rng(seed)
    noisy = clean + rng.standard_normal(clean.shape) * np.sqrt(a + b * clean)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def _ramp(h: int = 480, w: int = 640) -> np.ndarray:
    """A plain surface under uneven light: grey levels 30-220 across, smoothly."""
    x = np.linspace(0.0, 1.0, w)[None, :]
    y = np.linspace(0.0, 1.0, h)[:, None]
    return 30.0 + 190.0 * (0.6 * x + 0.4 * y ** 2)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("background", ["plain", "photo"])
def test_the_noise_level_is_read_from_the_image(seed, background):
    """Noise drawn at random (read-out floor a 0-4, shot noise b 0.005-0.05 grey levels per grey level) on a
    plain ramp and on a photograph (scikit-image's camera man, textured over most of its frame; blurred 1.5 px
    first, so that the scan's own grain, about 4 grey levels, is not in the truth): the level's standard
    deviation at grey levels 50, 120 and 200 within 15 % of the planted one (the 8 bits' own quantisation,
    variance 1/12, counted in it)."""
    rng = np.random.default_rng(100 + seed)
    a, b = rng.uniform(0.0, 4.0), rng.uniform(0.005, 0.05)
    photo = cv2.GaussianBlur(data.camera().astype(np.float64), (0, 0), 1.5)
    clean = _ramp() if background == "plain" else 20.0 + 0.85 * photo
    level = noise_level(_noisy(clean, a, b, seed))
    for grey in (50.0, 120.0, 200.0):
        truth = np.sqrt(a + b * grey + 1.0 / 12.0)
        assert float(level.sigma(grey)) == pytest.approx(truth, rel=0.15), (a, b, grey, level)


@pytest.mark.parametrize("seed", range(3))
def test_a_flat_frame_is_taken_for_texture_at_the_stated_rate(seed):
    """Plain surfaces under uneven light, noise drawn at random: at most the scales' false alarms (each
    FALSE_ALARM of the pixels) in all, with room for the estimate's error."""
    rng = np.random.default_rng(200 + seed)
    img = _noisy(_ramp(600, 800), rng.uniform(0.0, 4.0), rng.uniform(0.005, 0.05), seed)
    assert textured_pixels(img).mean() <= 3 * len(SCALES) * FALSE_ALARM


def test_a_textured_patch_is_found_and_its_plain_surround_is_not():
    """A photograph's patch (scikit-image's gravel, 200 x 200 px) in a plain noisy frame: its pixels 3 px or more
    inside it are textured (>= 97 %), the surround 4 px or more outside it is not (<= 0.5 %)."""
    clean = np.full((400, 600), 90.0)
    clean[100:300, 200:400] = 40.0 + 0.6 * data.gravel()[:200, :200]
    tex = textured_pixels(_noisy(clean, 1.0, 0.02, 5))
    inner = np.zeros(clean.shape, bool)
    inner[103:297, 203:397] = True
    near = np.zeros(clean.shape, bool)
    near[96:304, 196:404] = True
    assert tex[inner].mean() >= 0.97
    assert tex[~near].mean() <= 0.005


def test_the_noise_quantile_is_the_statistics_own():
    """K, the window RMS that unit white noise exceeds with the false alarm: the table's the seeded draw's, and
    the same from another draw of noise (a Monte-Carlo of our own, a fresh seed) within 3 %, and the mean
    square of the band on noise is the band filter's own energy (1 - 2 g(0) + sum g^2 for the image minus its
    blur, from OpenCV's Gaussian kernel; the difference of two blurs likewise) within 1 %."""
    rng = np.random.default_rng(7)
    z = rng.standard_normal((1024, 1024)).astype(np.float32)
    for sigma, window in SCALES:
        k1 = cv2.getGaussianKernel(2 * int(np.ceil(4 * sigma)) + 1, sigma)[:, 0]
        if sigma <= 1.0:
            h1 = -np.outer(k1, k1)
            h1[len(k1) // 2, len(k1) // 2] += 1.0
        else:
            k2 = cv2.getGaussianKernel(len(k1), sigma / 2)[:, 0]
            h1 = np.outer(k2, k2) - np.outer(k1, k1)
        energy = float((h1 ** 2).sum())
        fine = z if sigma <= 1.0 else cv2.GaussianBlur(z, (0, 0), sigma / 2, borderType=cv2.BORDER_REFLECT)
        band = fine - cv2.GaussianBlur(z, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
        assert float((band[16:-16, 16:-16] ** 2).mean()) == pytest.approx(energy, rel=0.01)
        r = np.sqrt(np.maximum(cv2.boxFilter(band * band, -1, (window, window)), 0))[16:-16, 16:-16]
        assert noise_quantile(sigma, window) == pytest.approx(float(np.quantile(r, 1 - FALSE_ALARM)), rel=0.03)
        assert noise_quantile(sigma, window) == pytest.approx(simulated_quantile(sigma, window), rel=1e-6)
    other = noise_quantile(1.0, 3, 0.01)            # not in the table: drawn
    assert other == pytest.approx(simulated_quantile(1.0, 3, 0.01), rel=1e-12) and other < 1.576


def test_bad_input_is_refused_in_words():
    with pytest.raises(ValueError, match="at least 5 px a side"):
        noise_level(np.zeros((3, 40)))
    with pytest.raises(ValueError, match="grey image"):
        noise_level(np.zeros((10, 10, 3)))
    assert NoiseLevel(1.0, 0.0).sigma(np.array([0.0, 100.0])).tolist() == [1.0, 1.0]
    assert not textured_pixels(np.full((40, 40), 77, np.uint8)).any()      # no noise, no texture: nothing
