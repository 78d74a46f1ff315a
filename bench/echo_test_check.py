"""The dense trust's false-alarm rate, run on demand (a few minutes, not in the suite; docs/dense.md, "Which
answers to trust"): psvs.dense.echo_test on N images without echo, of random size (0.05-1.3 MP at the judged
level, i.e. what any camera's pyramid level gives), kind (independent pixels; a wall of sensor noise; noise
blurred 0.6-4 px; a vignetted wall saved as JPEG at quality 70-95; a shaded wall, smooth light and noise; a
Bayer-mosaicked colour wall demosaiced and turned to luma), and lag range (from 0 or from 3-20 % of the width,
40-300 lags); and on the same images with a planted echo (a copy of a photo patch placed d px to the left of
itself, mixed as a PSVS mixes its two views, 40/60 to 60/40): how often the test judges an echo.

    python bench/echo_test_check.py [N] [SEED]

Prints each kind's false alarms (of N / 6) and the planted echoes found, the largest strongest/threshold
ratio seen on images without echo, and the test's time per image.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from psvs.dense.echo_test import ALPHA, echo_test  # noqa: E402

KINDS = ("noise", "wall", "blurred", "jpeg wall", "shaded wall", "bayer wall")


def no_echo(kind: str, h: int, w: int, rng) -> np.ndarray:
    """An image of ``kind`` without echo, (h, w) float64 grey levels 0..255."""
    if kind == "noise":
        return rng.integers(0, 256, (h, w)).astype(np.float64)
    if kind == "wall":
        return np.round(np.clip(128 + rng.normal(0, rng.uniform(0.5, 4), (h, w)), 0, 255))
    if kind == "blurred":
        return cv2.GaussianBlur(rng.normal(128, 40, (h, w)), (0, 0), rng.uniform(0.6, 4))
    yy, xx = np.mgrid[0:h, 0:w]
    vignette = 150 - 40 * ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / (w * w / 4)
    if kind == "jpeg wall":
        wall = np.clip(vignette + rng.normal(0, 2, (h, w)), 0, 255).astype(np.uint8)
        q = int(rng.integers(70, 96))
        return cv2.imdecode(cv2.imencode(".jpg", wall, [cv2.IMWRITE_JPEG_QUALITY, q])[1], 0).astype(np.float64)
    if kind == "shaded wall":
        light = cv2.resize(rng.normal(0, 20, (max(2, h // 40), max(2, w // 40))), (w, h), interpolation=cv2.INTER_CUBIC)
        return np.clip(vignette + light + rng.normal(0, 1.5, (h, w)), 0, 255)
    mosaic = np.clip(vignette + rng.normal(0, 3, (h, w)), 0, 255).astype(np.uint8)      # one value per photosite
    bgr = cv2.cvtColor(mosaic, cv2.COLOR_BayerRG2BGR)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float64)


def planted(img: np.ndarray, d: int, rng) -> np.ndarray:
    """``img`` with a photo patch (a third of it, from scikit-image's astronaut) seen by both views: at x in
    the left view and at x - d in the right one, mixed (1 - s) L + s R."""
    from skimage import data
    h, w = img.shape
    photo = cv2.cvtColor(data.astronaut(), cv2.COLOR_RGB2GRAY).astype(np.float64)
    ph, pw = h // 2, max(16, min(w // 3, w - d - 2))           # the patch and its twin inside the image
    patch = cv2.resize(photo, (pw, ph), interpolation=cv2.INTER_AREA)
    y0, x0 = (h - ph) // 2, d + (w - d - pw) // 2
    s = rng.uniform(0.4, 0.6)
    left, right = img.copy(), img.copy()
    left[y0:y0 + ph, x0:x0 + pw] = patch
    right[y0:y0 + ph, x0 - d:x0 - d + pw] = patch
    return (1 - s) * left + s * right


def main(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    stats = {k: [0, 0, 0, 0.0] for k in KINDS}          # images, false alarms, planted found, worst ratio
    times = []
    for i in range(n):
        kind = KINDS[i % len(KINDS)]
        area = rng.uniform(0.05, 1.3) * 1e6
        aspect = rng.uniform(1.0, 1.8)
        h, w = int(np.sqrt(area / aspect)), int(np.sqrt(area * aspect))
        lo = 0.0 if rng.random() < 0.3 else float(rng.uniform(0.03, 0.2) * w)
        hi = float(min(w - 40, lo + rng.uniform(40, 300)))
        img = no_echo(kind, h, w, rng)
        t0 = time.perf_counter()
        res = echo_test(img, lo, hi)
        times.append(time.perf_counter() - t0)
        d = int(rng.integers(max(int(np.ceil(lo)), 12), int(hi)))
        found = echo_test(planted(img, d, rng), lo, hi)
        st = stats[kind]
        st[0] += 1
        st[1] += int(res.strongest > 1.0)
        st[2] += int(found.echoes and abs(found.strongest_at[3] - d) <= 2)
        st[3] = max(st[3], res.strongest)
    total = sum(s[0] for s in stats.values())
    alarms = sum(s[1] for s in stats.values())
    print(f"echo test at alpha = {ALPHA:.0%}: {alarms} false alarm(s) in {total} images without echo "
          f"({alarms / total:.2%}); planted echoes found at their disparity: "
          f"{sum(s[2] for s in stats.values())} of {total}; {np.median(times) * 1e3:.0f} ms per image (median)")
    for kind, (m, fa, found, worst) in stats.items():
        print(f"  {kind:12s} {m:4d} images  false alarms {fa}  planted found {found}  largest ratio {worst:.2f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 600, int(sys.argv[2]) if len(sys.argv) > 2 else 2026)
