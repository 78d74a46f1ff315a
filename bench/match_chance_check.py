"""The automatic matcher's chance level, run on demand (minutes, not in the suite; docs/matching.md, "Twins
against chance"): ``psvs match --auto`` (psvs.match.correspondence.match_image) on N complex images without
twins, drawn at random over kinds (independent pixels; noise blurred 0.6-4 px; salt and pepper on a shaded
wall; clutter of random shapes of random sizes; stripes and checkerboards of random period and angle; one
view only of a photograph: scikit-image's camera, coins, text, brick, grass, gravel, page, moon, cropped at
random) and rigs (the shipped default 640 x 480, mv1440 1440 x 1080 and the misaligned build); and on
images *with* twins (on the default rig, the one of the paper's geometry: on a build a shifted copy is no
twin of the rectified rows): 1-4 bright objects of random shape on a dark
table seen by both views, the right view d px to the left of the left one (d drawn in the rig's range),
mixed as a PSVS mixes its two views (40/60 to 60/40). Counts how often an image without twins is answered
(the false alarms) and how often one with twins is, with its pairs' disparities within 2 px of d (the
power).

    python bench/match_chance_check.py [N] [SEED]
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from psvs.io.params import load_rig  # noqa: E402
from psvs.match.correspondence import MatchParams, match_image  # noqa: E402
from psvs.optics.search_range import rectification_for  # noqa: E402

RIGS = ("default", "mv1440", "misaligned")
KINDS = ("noise", "blurred", "salt and pepper", "shapes", "periodic", "one view")
PHOTOS = ("camera", "coins", "text", "brick", "grass", "gravel", "page", "moon")


def photo(name: str, h: int, w: int, rng) -> np.ndarray:
    """A random crop of scikit-image's photograph ``name``, resized to (h, w), grey float64 0..255."""
    from skimage import data
    img = getattr(data, name)()
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    ih, iw = img.shape
    ch, cw = int(ih * rng.uniform(0.5, 1.0)), int(iw * rng.uniform(0.5, 1.0))
    y0, x0 = int(rng.integers(0, ih - ch + 1)), int(rng.integers(0, iw - cw + 1))
    return cv2.resize(img[y0:y0 + ch, x0:x0 + cw].astype(np.float64), (w, h), interpolation=cv2.INTER_AREA)


def no_twins(kind: str, h: int, w: int, rng) -> np.ndarray:
    """An image of ``kind`` without twins, (h, w) float64 grey levels 0..255."""
    if kind == "noise":
        return rng.integers(0, 256, (h, w)).astype(np.float64)
    if kind == "blurred":
        return cv2.GaussianBlur(rng.normal(110, 50, (h, w)), (0, 0), rng.uniform(0.6, 4))
    if kind == "salt and pepper":
        img = np.full((h, w), 150.0) + rng.normal(0, 3, (h, w))
        hit = rng.random((h, w)) < rng.uniform(0.01, 0.2)
        img[hit] = rng.choice([0.0, 255.0], hit.sum())
        return img
    if kind == "shapes":
        img = np.full((h, w), 180.0)
        for _ in range(int(rng.integers(5, 40))):
            c = (int(rng.integers(0, w)), int(rng.integers(0, h)))
            axes = (int(rng.integers(5, w // 6)), int(rng.integers(5, h // 4)))
            cv2.ellipse(img, c, axes, float(rng.uniform(0, 180)), 0, 360, float(rng.uniform(0, 80)), -1)
        return img
    if kind == "periodic":
        yy, xx = np.mgrid[0:h, 0:w].astype(float)
        a, period = rng.uniform(0, np.pi), rng.uniform(8, w / 4)
        s = (np.cos(a) * xx + np.sin(a) * yy) / period
        if rng.random() < 0.5:
            return 40 + 180 * (np.floor(s) % 2)
        t = (-np.sin(a) * xx + np.cos(a) * yy) / period
        return 40 + 180 * ((np.floor(s) + np.floor(t)) % 2)
    return photo(str(rng.choice(PHOTOS)), h, w, rng)


def with_twins(h: int, w: int, d: int, rng) -> np.ndarray:
    """Objects on a dark table seen by both views (the paper's Fig. 5a): 1-4 bright ellipses of random
    size and grey in the left view, the right view the left one d px to its left, mixed (1 - s) L + s R
    with s in 0.4..0.6."""
    left = np.full((h, w), float(rng.uniform(5, 40)))
    for _ in range(int(rng.integers(1, 5))):
        c = (int(rng.integers(d, w)), int(rng.integers(h // 6, h - h // 6)))
        axes = (int(rng.integers(8, w // 10)), int(rng.integers(h // 12, h // 4)))
        cv2.ellipse(left, c, axes, float(rng.uniform(0, 180)), 0, 360, float(rng.uniform(200, 255)), -1)
    right = np.full_like(left, left[0, 0])
    right[:, :w - d] = left[:, d:]
    s = rng.uniform(0.4, 0.6)
    return (1 - s) * left + s * right


def main(n: int = 60, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    rigs = {name: load_rig(Path(__file__).resolve().parents[1] / "examples" / "rigs" / f"{name}.toml")
            for name in RIGS}
    params = MatchParams(subpixel=False)
    false, power, worst, t0 = {k: 0 for k in KINDS}, [0, 0, 0], 0.0, time.perf_counter()
    for k in range(n):
        name = RIGS[k % len(RIGS)]
        rig = rigs[name]
        w, h = rig.camera.image_size_px
        kind = KINDS[(k // len(RIGS)) % len(KINDS)]
        img = np.clip(no_twins(kind, h, w, rng), 0, 255).astype(np.uint8)
        res = match_image(img, rig, params=params)
        worst = max(worst, res.chance.strongest_rows / max(res.chance.level_rows, 1.0))
        if res.pairs:
            false[kind] += 1
            print(f"false alarm: {kind} on {name}: {len(res.pairs)} pairs; {res.chance.describe()}")
        if rectification_for(rig, 400.0, 1200.0) is not None:   # a build (mv1440's lens, misaligned mirrors):
            continue                                             # a shifted copy is no twin of its rows
        lo, hi = res.disparity_range_px
        d = int(rng.integers(int(lo) + 2, int(hi) - 1))
        twin = np.clip(with_twins(h, w, d, rng), 0, 255).astype(np.uint8)
        got = match_image(twin, rig, params=params)
        right = [p for p in got.pairs if abs(p.shape_disparity_px - d) <= 2]
        power[0] += bool(right)
        power[1] += len(got.pairs) - len(right)
        power[2] += 1
    per_kind = ", ".join(f"{k} {v}" for k, v in false.items())
    print(f"{n} images without twins: {sum(false.values())} answered ({per_kind}); the strongest twin at most "
          f"{worst:.2f} times chance's level")
    print(f"{power[2]} images with twins: {power[0]} answered at their disparity; {power[1]} pairs at another "
          f"disparity")
    print(f"{time.perf_counter() - t0:.0f} s in all")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
