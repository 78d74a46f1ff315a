"""View separation of the same scene through the 640 x 480 `clear` rig and mv1440 (1440 x 1080, 3.45 um,
8 mm: 2.05 px per paper px; through its rectification): photo cards before a façade (tests/dense/facade.py)
over 550-1100 mm. Each separated view against that view rendered alone (a noiseless sensor), over the
pixels whose twin lies in the frame, with the true disparities and with the dense search's. Measured
(docs/dense.md, "The prior in scene terms"), seed 0, left / right dB: clear true 23.9 / 23.9, estimated
23.7 / 23.4 (mixture 20.1 / 19.6); mv1440 true 24.7 / 24.6, estimated 24.4 / 23.9 (mixture 20.6 / 18.8)."""
import functools
from dataclasses import replace

import numpy as np
import pytest

from psvs.dense.build import dense_on_rig, rectified_images
from psvs.dense.separate import SeparationParams, grid_pixel_scale, psnr_db, separate_views
from psvs.io.params import load_rig
from psvs.optics.illumination import flat_field
from psvs.optics.scale import pixel_scale
from psvs.optics.search_range import rectification_for
from psvs.simulate.render import render
from psvs.simulate.sensor import Sensor, expose
from tests.dense.facade import cards_before_facade
from tests.dense.planted import layered_pair

NEAR_MM, FAR_MM = 550.0, 1100.0


def rectified_truth(rect, depth_mm: np.ndarray, view: str) -> np.ndarray:
    """The true rectified disparity u'_l − u'_r (> 0) on ``view``'s grid: each grid pixel's complex-image
    depth (nearest pixel) put on its rectified ray and projected into the other view's rectified camera."""
    w, h = rect.size_px
    uu, vv = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    c = rect.lookup(uv, view)
    z = np.full(h * w, np.nan)
    ok = np.all(np.isfinite(c), axis=1)
    ci = np.rint(c[ok]).astype(int)
    z[ok] = depth_mm[ci[:, 1], ci[:, 0]]
    p, centre = rect.rays(uv, view), rect.centres_mm[view]
    points = centre + ((z - centre[2]) / (p[:, 2] - centre[2]))[:, None] * (p - centre)
    K, q = rect.camera_matrix, (points - rect.centres_mm["right" if view == "left" else "left"]) @ rect.rotation.T
    with np.errstate(invalid="ignore"):
        u_other = K[0, 0] * q[:, 0] / q[:, 2] + K[0, 2]
    return (uv[:, 0] - u_other if view == "left" else u_other - uv[:, 0]).reshape(h, w)


@functools.lru_cache(maxsize=None)
def _scene(rig_name: str, seed: int) -> dict:
    """The scene through ``rig_name``: the flattened complex image, the true and the estimated maps, each
    view alone and the mixture on its grid, and the pixels scored (twin in the frame)."""
    rig = load_rig(rig_name)
    rr = render(cards_before_facade(seed), rig, truth=True, seed=seed)
    rect = rectification_for(rig, NEAR_MM, FAR_MM)
    clean = replace(Sensor(), shot_noise=False, read_noise_e=0.0)
    alone = (expose(rr.left, clean), expose(rr.right, clean))
    seen, t = flat_field(rr.image, rig.camera), rr.truth
    if rect is None:
        true_maps = (np.where(t.valid_left, t.disparity_left_px, np.nan),
                     np.where(t.valid_right, t.disparity_right_px, np.nan))
        truths, mixes, masks = alone, (seen, seen), (t.valid_left, t.valid_right)
    else:
        true_maps = (rectified_truth(rect, np.where(t.valid_left, t.depth_left_mm, np.nan), "left"),
                     rectified_truth(rect, np.where(t.valid_right, t.depth_right_mm, np.nan), "right"))
        truths = (rectified_images(alone[0], rect)[0], rectified_images(alone[1], rect)[1])
        mixes = rectified_images(seen, rect)
        u, w = np.arange(rect.size_px[0]), rect.size_px[0]
        with np.errstate(invalid="ignore"):
            masks = (np.isfinite(true_maps[0]) & (u - true_maps[0] >= 0) & (rect.maps("left")[0] >= 0),
                     np.isfinite(true_maps[1]) & (u + true_maps[1] <= w - 1) & (rect.maps("right")[0] >= 0))
    dense = dense_on_rig(rr.image, rig, NEAR_MM, FAR_MM).result
    return {"seen": seen, "split": rig.mirrors.split_ratio, "rect": rect, "truths": truths, "mixes": mixes,
            "masks": masks, "maps": {"true": true_maps, "estimated": (dense.disparity_left, dense.disparity_right)},
            "scale": pixel_scale(rig.camera) if rect is None else None}


@functools.lru_cache(maxsize=None)
def separated(rig_name: str, seed: int = 0, params: SeparationParams = SeparationParams(),
              pixel_scale_override: float | None = None) -> dict:
    """{'mixture' | 'true' | 'estimated': (left dB, right dB)} of the scene through ``rig_name``; the prior
    scaled to the camera unless ``pixel_scale_override`` (1.0: λ per pixel, as before it was scaled)."""
    sc = _scene(rig_name, seed)

    def scores(views):
        return tuple(psnr_db(np.asarray(v, float)[m], np.asarray(tr, float)[m])
                     for v, tr, m in zip(views, sc["truths"], sc["masks"], strict=True))

    k = sc["scale"] if pixel_scale_override is None else pixel_scale_override
    out = {"mixture": scores(sc["mixes"])}
    for name, (dl, dr) in sc["maps"].items():
        out[name] = scores(separate_views(sc["seen"], dl, sc["split"], dr, params=params, rect=sc["rect"],
                                          pixel_scale=k))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("rig_name, true_db, estimated_db", [("clear", 23.4, 23.0), ("mv1440", 24.1, 23.4)])
def test_separated_views_on_both_cameras(rig_name, true_db, estimated_db):
    got = separated(rig_name, 0)
    for view in (0, 1):
        assert got["true"][view] > true_db, got
        assert got["estimated"][view] > estimated_db, got
        assert got["true"][view] > got["mixture"][view] + 3.0, got
        assert got["estimated"][view] > got["mixture"][view] + 2.5, got


@pytest.mark.slow
def test_the_finer_camera_separates_at_least_as_well():
    """The same scene: mv1440's views are no further from the truth than the 640 x 480 rig's (0.3 dB)."""
    fine, coarse = separated("mv1440", 0), separated("clear", 0)
    for name in ("true", "estimated"):
        for view in (0, 1):
            assert fine[name][view] >= coarse[name][view] - 0.3, (name, view, fine, coarse)


def test_the_prior_is_scaled_by_the_square_of_the_pixel_scale():
    """λ given on the paper's camera acts as λ·k² on a grid of k px per paper px; a build's grid has its own k."""
    left, right, tl, tr = layered_pair()
    c = 0.5 * left + 0.5 * right
    scaled = separate_views(c, tl, 0.5, tr, params=SeparationParams(smoothness=0.05), pixel_scale=2.0)
    direct = separate_views(c, tl, 0.5, tr, params=SeparationParams(smoothness=0.2))
    for a, b in zip(scaled, direct, strict=True):
        np.testing.assert_array_equal(a, b)
    plain = separate_views(c, tl, 0.5, tr)
    assert np.abs(scaled[0] - plain[0]).max() > 0.1               # and the scale does change the answer
    rig = load_rig("mv1440")
    assert grid_pixel_scale(rectification_for(rig, NEAR_MM, FAR_MM)) == pytest.approx(pixel_scale(rig.camera), rel=0.01)


@pytest.mark.parametrize("kwargs, message", [({"smoothness": 0.0}, "smoothness"), ({"coupling": -1.0}, "coupling"),
                                             ({"iterations": 0}, "iterations"), ({"iterations": 2.5}, "iterations")])
def test_bad_separation_params_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        SeparationParams(**kwargs)


def test_bad_pixel_scale_is_named():
    left, right, tl, _ = layered_pair()
    with pytest.raises(ValueError, match="pixel_scale"):
        separate_views(0.5 * left + 0.5 * right, tl, pixel_scale=0.0)
