"""Pipeline steps (paper III.3 step 1: "filtering, edge detection, binary conversion ... any combination of
different filters and edge detection algorithms"), thin wrappers over OpenCV and scikit-image.

Grey images are (H, W) uint8 (OpenCV's fast path; the paper's threshold 92 is a grey level); binary
images and edge maps are (H, W) bool. Each step takes an image and keyword parameters and returns an image.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from psvs._budget import check_time


def _grey(img: np.ndarray, step: str) -> np.ndarray:
    if img.dtype == bool:
        return img.astype(np.uint8) * 255
    if img.dtype != np.uint8:
        raise ValueError(f"{step}: expected a uint8 grey or bool image, got {img.dtype}")
    return img


#: What each step parameter may be, checked when a pipeline's step is made (psvs.imaging.pipeline.Step: a
#: pipeline file, the web page's steps, the library's own), so that every caller refuses the same values:
#: (kind, smallest, largest), kind "odd" (an odd integer), "int" or "real" (a finite number; bounds inclusive,
#: None: open). A value OpenCV refuses with an assertion (an adaptive threshold's 1 px block) or takes without a
#: word (a NaN offset or sigma: a frame of noise) is bad input, said in one line, not a measurement's failure.
PARAM_RULES = {"ksize": ("odd", 1, None), "diameter": ("int", 1, None), "block": ("odd", 3, None),
               "sigma": ("real", 0.0, None), "sigma_color": ("real", 0.0, None), "sigma_space": ("real", 0.0, None),
               "level": ("real", 0.0, None), "low": ("real", 0.0, None), "high": ("real", 0.0, None),
               "offset": ("real", -255.0, 255.0)}
#: The parameters that must be above their smallest value, not at it (a Gaussian or a bilateral of sigma 0).
_ABOVE = ("sigma", "sigma_color", "sigma_space")
#: The threshold's methods.
METHODS = ("fixed", "otsu", "adaptive")


def check_param(op: str, name: str, value) -> None:
    """ValueError naming ``op``'s parameter ``name`` when ``value`` breaks :data:`PARAM_RULES` (or ``method``
    is not one of :data:`METHODS`)."""
    if name == "method":
        if value not in METHODS:
            raise ValueError(f"{op} method must be fixed, otsu or adaptive, got {value!r}")
        return
    kind, low, high = PARAM_RULES[name]
    whole = kind in ("odd", "int")
    if isinstance(value, bool) or not isinstance(value, int if whole else (int, float)) or not math.isfinite(value):
        what = {"odd": "an odd integer", "int": "an integer", "real": "a finite number"}[kind]
        raise ValueError(f"{op} {name} must be {what}, got {value!r}")
    below = value <= low if name in _ABOVE else value < low
    if below or (high is not None and value > high) or (kind == "odd" and value % 2 == 0):
        span = (f"> {low:g}" if name in _ABOVE else f">= {low:g}") + ("" if high is None else f" and <= {high:g}")
        raise ValueError(f"{op} {name} must be {'an odd integer' if kind == 'odd' else 'a number'} {span}, "
                         f"got {value!r}")


def _odd(k, name: str, img: np.ndarray | None = None) -> int:
    if not isinstance(k, int) or k < 1 or k % 2 == 0:
        raise ValueError(f"{name} must be an odd integer >= 1, got {k!r}")
    if img is not None:
        _within(k, name, img)
    return k


def _within(size: float, name: str, img: np.ndarray) -> None:
    """ValueError when a window of ``size`` px is wider than the image's larger side: every pixel's window
    would hold the whole image (and the padded copy OpenCV makes grows with it: a diameter of 100000 asked
    for 17 GB)."""
    side = max(img.shape[:2])
    if not size <= side:       # NaN too
        raise ValueError(f"{name} {size:g} px is wider than the image ({img.shape[1]}x{img.shape[0]} px): a window "
                         f"at most {side} px wide")


#: s per pixel and window tap of OpenCV's bilateral filter (0.12 s for a 31 px diameter at 640x480, 2.9 s
#: for 101 px, on the 2-core reference machine): its time is estimated before it runs.
BILATERAL_S_PER_TAP = 1.2e-9


# --- filters: grey -> grey ---------------------------------------------------------------------------

#: Largest median window: OpenCV's constant-time median of 8-bit images fails an internal assertion on some
#: images from about 363 px up (fig5b: 363; a striped frame: 393).
MEDIAN_MAX_PX = 255


def median(img, ksize: int = 3):
    """Median filter, ksize x ksize (the paper's filter), ksize at most :data:`MEDIAN_MAX_PX`."""
    k = _odd(ksize, "median ksize", img)
    if k > MEDIAN_MAX_PX:
        raise ValueError(f"median ksize must be at most {MEDIAN_MAX_PX} px, got {k}")
    return cv2.medianBlur(_grey(img, "median"), k)


def gaussian(img, sigma: float = 1.0):
    """Gaussian filter of standard deviation sigma (px)."""
    if not sigma > 0:
        raise ValueError(f"gaussian sigma must be > 0 px, got {sigma!r}")
    _within(6 * sigma + 1, "gaussian window (6 sigma + 1)", img)
    k = 2 * int(np.ceil(3 * sigma)) + 1
    return cv2.GaussianBlur(_grey(img, "gaussian"), (k, k), sigma)


def mean(img, ksize: int = 3):
    """Box (mean) filter, ksize x ksize."""
    k = _odd(ksize, "mean ksize", img)
    return cv2.blur(_grey(img, "mean"), (k, k))


def bilateral(img, diameter: int = 5, sigma_color: float = 25.0, sigma_space: float = 3.0):
    """Edge-preserving bilateral filter (OpenCV): a window of ``diameter`` px (at most the image's larger
    side), its time estimated first (:data:`BILATERAL_S_PER_TAP`; psvs._budget's limit)."""
    if not isinstance(diameter, int) or diameter < 1:
        raise ValueError(f"bilateral diameter must be an integer >= 1 px, got {diameter!r}")
    _within(diameter, "bilateral diameter", img)
    h, w = img.shape[:2]
    check_time(h * w * 0.785 * diameter ** 2 * BILATERAL_S_PER_TAP,
               f"a bilateral filter of diameter {diameter} px on {w}x{h} px", "a smaller diameter")
    return cv2.bilateralFilter(_grey(img, "bilateral"), diameter, sigma_color, sigma_space)


# --- binarisation: grey -> bool ------------------------------------------------------------------------

def threshold(img, level: int = 92, method: str = "fixed", block: int = 31, offset: float = 5.0):
    """Binary image: ``fixed`` (grey > level; the paper uses 92), ``otsu`` or ``adaptive`` (local mean of a
    block x block window minus offset)."""
    g = _grey(img, "threshold")
    if method == "fixed":
        if not 0 <= level <= 255:
            raise ValueError(f"threshold level must be a grey level 0-255, got {level!r}")
        _, b = cv2.threshold(g, level, 1, cv2.THRESH_BINARY)   # grey > level -> 1 (OpenCV, SIMD)
        return b.view(bool)
    if method == "otsu":
        _, b = cv2.threshold(g, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        return b > 0
    if method == "adaptive":
        for name, value in (("block", block), ("offset", offset)):      # (a library call: no Step made them)
            check_param("threshold", name, value)
        b = cv2.adaptiveThreshold(g, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY, block, offset)
        return b > 0
    raise ValueError(f"threshold method must be fixed, otsu or adaptive, got {method!r}")


# --- edges: grey or bool -> bool -----------------------------------------------------------------------

def roberts(img, level: float = 0.0):
    """Roberts cross (the paper's detector). On a binary image it is exact and cheap: a pixel is an edge
    when it differs from a diagonal neighbour (|G1| + |G2| > 0). On a grey image: |G1| + |G2| > level."""
    out = np.zeros(img.shape, dtype=np.uint8)
    if img.dtype == bool:
        b = img.view(np.uint8)
        d1 = cv2.bitwise_xor(b[:-1, :-1], b[1:, 1:])
        d2 = cv2.bitwise_xor(b[:-1, 1:], b[1:, :-1])
        out[:-1, :-1] = cv2.bitwise_or(d1, d2)
        return out.view(bool)
    g = _grey(img, "roberts").astype(np.int16)
    mag = np.abs(g[:-1, :-1] - g[1:, 1:]) + np.abs(g[:-1, 1:] - g[1:, :-1])
    out[:-1, :-1] = mag > level
    return out.view(bool)


def _gradient_edges(img, kx, ky, level, step):
    g = _grey(img, step).astype(np.float32)
    gx = cv2.filter2D(g, cv2.CV_32F, kx)
    gy = cv2.filter2D(g, cv2.CV_32F, ky)
    return np.hypot(gx, gy) > level


def sobel(img, level: float = 60.0):
    """Sobel gradient magnitude > level."""
    kx = np.array([[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]], np.float32)
    return _gradient_edges(img, kx, kx.T.copy(), level, "sobel")


def prewitt(img, level: float = 50.0):
    """Prewitt gradient magnitude > level."""
    kx = np.array([[-1, 0, 1], [-1, 0, 1], [-1, 0, 1]], np.float32)
    return _gradient_edges(img, kx, kx.T.copy(), level, "prewitt")


def laplacian(img, level: float = 20.0):
    """Zero crossings of the Laplacian whose local contrast exceeds level."""
    lap = cv2.Laplacian(_grey(img, "laplacian").astype(np.float32), cv2.CV_32F, ksize=3)
    out = np.zeros(lap.shape, dtype=bool)
    for a, b in ((lap[:, :-1], lap[:, 1:]), (lap[:-1, :], lap[1:, :])):
        cross = (np.sign(a) * np.sign(b) < 0) & (np.abs(a - b) > level)
        if a.shape[1] != lap.shape[1]:
            out[:, :-1] |= cross
        else:
            out[:-1, :] |= cross
    return out


def canny(img, low: float = 50.0, high: float = 120.0):
    """Canny edges (OpenCV) with hysteresis thresholds 0 <= low <= high (an edge starts above high and
    continues above low; OpenCV swaps a low above high without a word: refused here, naming both)."""
    if not (isinstance(low, (int, float)) and isinstance(high, (int, float)) and 0 <= low <= high < math.inf):
        raise ValueError(f"canny thresholds must satisfy 0 <= low <= high (finite), got low={low!r}, high={high!r}")
    return cv2.Canny(_grey(img, "canny"), low, high, L2gradient=True) > 0


def thinning(img):
    """Thin an edge map to one-pixel-wide lines (scikit-image)."""
    from skimage.morphology import thin
    if img.dtype != bool:
        raise ValueError(f"thinning: expected a bool edge map, got {img.dtype}")
    return thin(img)


STEPS = {"median": median, "gaussian": gaussian, "mean": mean, "bilateral": bilateral, "threshold": threshold,
         "roberts": roberts, "sobel": sobel, "prewitt": prewitt, "laplacian": laplacian, "canny": canny,
         "thinning": thinning}
