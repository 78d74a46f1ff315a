"""Evaluation of dense complex-image disparity on real stereo pairs with ground truth.

A real rectified pair (L, R) is superimposed as a PSVS would, C = (1 − s)·L + s·R; the method runs on C
alone and is scored against the pair's ground truth beside OpenCV's StereoSGBM run on the *separate* pair.
Scores follow Middlebury: bad-k is the share (%) of ground-truth-valid pixels whose disparity is off by
more than k px, a missing answer (NaN) counting as wrong; MAE is over valid pixels with an answer.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import cv2
import numpy as np

from psvs.dense.disparity import dense_disparity
from psvs.dense.params import DEFAULT, FAST
from psvs.dense.separate import psnr_db, separate_views
from psvs.imaging.grey import to_grey8


def superimpose(left, right, split: float = 0.5) -> np.ndarray:
    """The complex image (1 − s)·L + s·R of a rectified pair, float64 (H, W)."""
    a, b = np.asarray(left, dtype=np.float64), np.asarray(right, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(f"left {a.shape} and right {b.shape} must be grey images of one size")
    return (1.0 - split) * a + split * b


def disparity_scores(estimate, truth) -> dict[str, float]:
    """bad-1, bad-2 (% of finite-truth pixels, NaN estimates wrong), MAE (px) and coverage (%)."""
    est, gt = np.asarray(estimate, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    if est.shape != gt.shape:
        raise ValueError(f"estimate {est.shape} and truth {gt.shape} differ in shape")
    valid = np.isfinite(gt)
    if not valid.any():
        raise ValueError("ground truth has no valid pixel")
    err = np.abs(est[valid] - gt[valid])
    answered = np.isfinite(err)
    return {"bad1_pct": 100.0 * float(np.mean(~(err <= 1.0))), "bad2_pct": 100.0 * float(np.mean(~(err <= 2.0))),
            "mae_px": float(np.mean(err[answered])) if answered.any() else float("nan"),
            "coverage_pct": 100.0 * float(np.mean(answered))}


#: The least share of the truth's valid pixels that must lie in the searched disparities (1 px either side):
#: a truth mostly outside them scores the search's range, not the method.
MIN_TRUTH_INSIDE = 0.5


def check_truth_range(truth, d_min: float, d_max: float) -> None:
    """ValueError naming the problem unless ``truth`` (H, W, px; NaN where none) can be a left view's disparity
    map searched over d_min..d_max px: every value in 0..W - 1 (a negative one is the right view's map, or
    the images swapped), and at least :data:`MIN_TRUTH_INSIDE` of them within d_min - 1..d_max + 1."""
    gt = np.asarray(truth, dtype=np.float64)
    vals = gt[np.isfinite(gt)]
    if vals.size == 0:
        raise ValueError("ground truth has no valid pixel")
    w = gt.shape[-1]
    for bad, what in ((vals < 0, "negative (a left view's disparity is >= 0: the right view's map, or the "
                                 "images swapped?)"),
                      (vals > w - 1, f"beyond the image's width ({w} px)")):
        if bad.any():
            raise ValueError(f"ground truth: {int(bad.sum())} of its {vals.size} valid pixels are {what}, e.g. "
                             f"{vals[bad][0]:g} px")
    inside = float(np.mean((vals >= d_min - 1.0) & (vals <= d_max + 1.0)))
    if inside < MIN_TRUTH_INSIDE:
        raise ValueError(f"only {100 * inside:.0f} % of the ground truth lies in the searched disparities "
                         f"{d_min:g}..{d_max:g} px (its median {np.median(vals):.1f} px, 1-99 % "
                         f"{np.percentile(vals, 1):.1f}..{np.percentile(vals, 99):.1f}): search the truth's range "
                         "(--min-disparity, --max-disparity)")


#: The offsets (px, either side) at which :func:`check_truth_fits` reads chance: the truth shifted by as much.
CHANCE_OFFSETS_PX = tuple(range(3, 16))
#: The band the views are compared in (their Gaussian blur of this sigma, px, taken off): texture, not shading.
FIT_BAND_SIGMA_PX = 2.0


def truth_fit(left, right, truth, offset_px: float = 0.0) -> float:
    """The normalised correlation (-1..1) of the left view with the right view warped by ``truth`` (+
    ``offset_px``): R(x - d(x), y) against L(x, y), band-passed (:data:`FIT_BAND_SIGMA_PX`), over the truth's
    valid pixels whose twin lies in the image. (H, W) grey images and truth (px, NaN where none)."""
    return _banded_fit(_band(left), _band(right), np.asarray(truth, dtype=np.float64), offset_px)


def _band(image) -> np.ndarray:
    a = np.asarray(image, dtype=np.float64)
    return a - cv2.GaussianBlur(a, (0, 0), FIT_BAND_SIGMA_PX)


def _banded_fit(left: np.ndarray, right: np.ndarray, gt: np.ndarray, offset_px: float) -> float:
    """:func:`truth_fit` of views already band-passed (:func:`_band`)."""
    h, w = gt.shape
    xs = (np.arange(w)[None, :] - np.nan_to_num(gt) - offset_px).astype(np.float32)
    ys = np.broadcast_to(np.arange(h, dtype=np.float32)[:, None], (h, w)).copy()
    warped = cv2.remap(right.astype(np.float32), xs, ys, cv2.INTER_LINEAR)
    seen = np.isfinite(gt) & (xs >= 0) & (xs <= w - 1)
    a, b = left[seen], warped[seen].astype(np.float64)
    a, b = a - a.mean(), b - b.mean()
    norm = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / norm if norm > 0 else 0.0


def check_truth_fits(left, right, truth) -> None:
    """ValueError unless ``truth`` is the disparity of this pair: the right view warped by it must match the left
    view at least twice as well as warped by the truth shifted 3-15 px either way (chance: what the texture's own
    likeness gives off the truth), and with a correlation of at least 0.1. Motorcycle: 0.81 against up to 0.07
    (its mirrored pair 0.90 against 0.08). An adversarial trial's planted pair scored with its views swapped gave
    psvs's own 2.1 % bad-2 (the superimposed image is the same) while the pair was the other way round
    (correlation 0.00 against 0.01); its truth at half scale, 100 % bad for every method (0.00 against up to
    0.78); one image given as both views (0.03 against 0.02): each is refused."""
    left, right = np.asarray(left, dtype=np.float64), np.asarray(right, dtype=np.float64)
    if left.shape != right.shape or left.shape != np.shape(truth):
        raise ValueError(f"left {left.shape}, right {right.shape} and ground truth {np.shape(truth)} must be of one "
                         "size")
    bl, br, gt = _band(left), _band(right), np.asarray(truth, dtype=np.float64)     # banded once, warped 27 times
    fit = _banded_fit(bl, br, gt, 0.0)
    chance = max(_banded_fit(bl, br, gt, s * k) for k in CHANCE_OFFSETS_PX for s in (-1, 1))
    if fit < max(2.0 * chance, 0.1):
        raise ValueError(f"the ground truth does not map the right view onto the left: warped by it, the right view "
                         f"correlates {fit:.2f} with the left, and {chance:.2f} with the truth shifted "
                         f"{CHANCE_OFFSETS_PX[0]}-{CHANCE_OFFSETS_PX[-1]} px (chance): the views swapped, one image "
                         "given twice, or a truth at another scale or of another pair?")


def sgbm_reference(left, right, d_max: int, block: int = 5) -> np.ndarray:
    """OpenCV StereoSGBM (3-way, ``block`` px) on the separate pair, disparities 0..d_max (rounded up to a
    multiple of 16; SGBM searches 0..n−1), NaN where it gives no answer: the usual settings P1 = 8·b², P2 = 32·b²,
    uniqueness 10, speckle window 100 / range 2, left-right check 1 px."""
    n = max(16, int(np.ceil(d_max / 16.0) * 16))
    m = cv2.StereoSGBM_create(minDisparity=0, numDisparities=n, blockSize=block, P1=8 * block * block,
                              P2=32 * block * block, disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=100,
                              speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    d = m.compute(to_grey8(left), to_grey8(right)).astype(np.float64) / 16.0
    d[d < 0] = np.nan
    return d


def mirrored(left, right, truth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pair seen in a mirror, a second test of one real pair: the left view is the right view flipped
    left-right, the right view the flipped left view, so each scene point swaps which view it is ghosted in.
    Its truth (the new left view's disparity, px) is the old left truth carried to each point's right-view
    column, x − d, the nearer point winning; NaN where no point lands (the old right view's occlusions)."""
    gt = np.asarray(truth, dtype=np.float64)
    h, w = gt.shape
    yy, xx = np.nonzero(np.isfinite(gt))
    d = gt[yy, xx]
    xr = np.rint(xx - d).astype(np.int64)
    inside = (xr >= 0) & (xr < w)
    yy, xr, d = yy[inside], xr[inside], d[inside]
    flat = np.full(h * w, -np.inf)
    np.maximum.at(flat, yy * w + (w - 1 - xr), d)
    out = flat.reshape(h, w)
    out[~np.isfinite(out)] = np.nan
    return np.fliplr(np.asarray(right)).copy(), np.fliplr(np.asarray(left)).copy(), out


def motorcycle() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Middlebury 2014 Motorcycle as shipped by scikit-image: grey left, grey right (0–255, float64, full
    size of that copy) and the left view's ground-truth disparity (px, NaN where unknown)."""
    from skimage import data
    from skimage.color import rgb2gray

    left, right, disp = data.stereo_motorcycle()
    gt = np.asarray(disp, dtype=np.float64)
    gt[~np.isfinite(gt)] = np.nan
    return rgb2gray(left) * 255.0, rgb2gray(right) * 255.0, gt


@dataclass(frozen=True)
class Evaluation:
    """Scores (see :func:`disparity_scores`) and wall times (s) of one pair, with the pictures."""

    scores: dict[str, dict[str, float]]   # method name -> scores
    seconds: dict[str, float]
    psnr_left_db: float
    psnr_right_db: float
    complex_image: np.ndarray
    disparity: np.ndarray
    truth: np.ndarray
    left_view: np.ndarray
    right_view: np.ndarray


def _warm(fn):
    """``fn()``'s result and the seconds of a second call (the first may compile or load kernels: a
    method's time is that of a run, not of its start)."""
    fn()
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def evaluate_pair(left, right, truth, d_min: float = 0.0, d_max: float = 64.0, split: float = 0.5) -> Evaluation:
    """Run the default and fast modes on the superimposed pair and StereoSGBM on the separate pair; each
    method's time is that of a second call (the first compiles or loads the kernels). ValueError before any
    work when the truth cannot be the left view's map over d_min..d_max (:func:`check_truth_range`) or does not
    map this pair's right view onto its left (:func:`check_truth_fits`)."""
    if not 0.0 < split < 1.0:                    # (NaN too)
        raise ValueError(f"split must lie strictly between 0 and 1 (the right view's share), got {split:g}")
    if not (math.isfinite(d_min) and math.isfinite(d_max) and d_min < d_max):
        raise ValueError(f"the searched disparities need min < max (--min-disparity, --max-disparity), got "
                         f"{d_min:g}..{d_max:g} px")
    check_truth_range(truth, d_min, d_max)
    check_truth_fits(left, right, truth)
    c = superimpose(left, right, split)
    scores, seconds, results = {}, {}, {}
    for name, params in (("psvs dense", DEFAULT), ("psvs dense --fast", FAST)):
        results[name], seconds[name] = _warm(lambda p=params: dense_disparity(c, d_min, d_max, params=p))
        scores[name] = disparity_scores(results[name].disparity_left, truth)
    best = results["psvs dense"]
    (lv, rv), seconds["view separation"] = _warm(lambda: separate_views(c, best.disparity_left, split,
                                                                         best.disparity_right))
    sg, seconds["StereoSGBM, separate pair"] = _warm(lambda: sgbm_reference(left, right, int(np.ceil(d_max))))
    scores["StereoSGBM, separate pair"] = disparity_scores(sg, truth)
    return Evaluation(scores, seconds, psnr_db(lv, left), psnr_db(rv, right), c, best.disparity_left,
                      np.asarray(truth, dtype=np.float64), lv, rv)
