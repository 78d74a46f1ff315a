"""Whether a pipeline's edges are the scene's or the sensor's noise (psvs.imaging.edge_noise): planted scenes of
steps under planted noise, drawn at random (sizes, contrasts, noise levels, seeds); a pipeline whose thresholds
sit at the scene's steps keeps its edges under a fresh draw of the noise, one whose thresholds sit at the noise's
own gradients does not, and on noise alone no pipeline's edges stand."""
import cv2
import numpy as np
import pytest

from psvs.imaging import MIN_STABLE_SHARE, PAPER, edge_stability, make_pipeline

CANNY_LOW = make_pipeline([{"op": "canny", "low": 2, "high": 6}])
CANNY_SANE = make_pipeline([{"op": "median", "ksize": 3}, {"op": "canny", "low": 40, "high": 120}])


def _scene(seed: int) -> tuple[np.ndarray, float]:
    """(frame (H, W) uint8, its noise sigma): discs and bars of random grey on a random background, blurred as a
    lens does (0.7-1.2 px), Gaussian noise of 0.5-3 grey levels."""
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(200, 400)), int(rng.integers(260, 520))
    yy, xx = np.mgrid[:h, :w]
    img = np.full((h, w), rng.uniform(30, 70))
    for _ in range(int(rng.integers(3, 8))):
        cx, cy, r = rng.uniform(0, w), rng.uniform(0, h), rng.uniform(15, 60)
        img[(xx - cx) ** 2 + (yy - cy) ** 2 < r * r] = rng.uniform(140, 230)
    img[:, int(rng.integers(10, w - 40)):][:, :int(rng.integers(8, 30))] = rng.uniform(100, 200)
    img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.7, 1.2))
    sigma = float(rng.uniform(0.5, 3.0))
    return np.clip(np.rint(img + rng.normal(0, sigma, img.shape)), 0, 255).astype(np.uint8), sigma


@pytest.mark.parametrize("seed", range(6))
def test_the_scenes_edges_stand_and_the_noises_do_not(seed):
    img, sigma = _scene(seed)
    for pipeline in (PAPER, CANNY_SANE):
        st = edge_stability(img, pipeline, seed=seed)
        assert st.edge_pixels > 200 and st.stable_share > 0.65 and not st.noise, (pipeline, st)
    st = edge_stability(img, CANNY_LOW, seed=seed)
    assert st.edge_pixels > 0.1 * img.size and st.stable_share < MIN_STABLE_SHARE and st.noise, st
    assert st.sigma_grey == pytest.approx(sigma, rel=0.25)                 # the level the draws used
    assert edge_stability(img, CANNY_LOW, seed=seed) == st                   # the same answer every time


def test_on_noise_alone_no_pipelines_edges_stand():
    """A flat grey frame with noise: whatever the thresholds that mark anything, the edges do not come back."""
    img = np.clip(np.rint(np.random.default_rng(5).normal(120, 2.0, (240, 320))), 0, 255).astype(np.uint8)
    for low, high in ((0, 0), (2, 6), (4, 10)):
        st = edge_stability(img, make_pipeline([{"op": "canny", "low": low, "high": high}]))
        assert st.edge_pixels > 100 and st.noise, (low, high, st)
    st = edge_stability(img, CANNY_SANE)          # nothing marked: nothing to call noise
    assert st.edge_pixels == 0 and st.stable_share == 1.0 and not st.noise


def test_the_refusal_says_what_it_measured():
    img, _ = _scene(2)
    st = edge_stability(img, CANNY_LOW)
    words = st.describe()
    assert words.startswith("the pipeline's edges are mostly the sensor's noise: with the frame's noise (")
    assert f"{100 * st.stable_share:.0f} % of the first draw's {st.edge_pixels} edge pixels come back" in words
    assert words.endswith("(60 % asked): raise the pipeline's thresholds, or smooth before its edge detector")
