"""Dual rectification: each view's epipolar curves become rows, checked with twin pixels
from the exact projection of random points (not the fit's own samples) on several builds."""
import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.optics.rectify import needs_rectification, rectify
from tests.support.rig_draws import random_build


def twins(rig, seed, n=3000, near=400.0, far=1200.0):
    """Random points (uniform in 1/Z over near..far, spread over the field) seen by both views inside the
    image: (points (N, 3), left px (N, 2), right px (N, 2))."""
    rng = np.random.default_rng(seed)
    z = 1.0 / rng.uniform(1.0 / far, 1.0 / near, n)
    pts = np.column_stack([rng.uniform(-0.45, 0.45, n) * z, rng.uniform(-0.22, 0.22, n) * z, z])
    w, h = rig.camera.image_size_px
    uv_l, ok_l = project_points(pts, rig, "left")
    uv_r, ok_r = project_points(pts, rig, "right")
    ok = ok_l & ok_r
    for uv in (uv_l, uv_r):
        with np.errstate(invalid="ignore"):
            ok &= (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
    return pts[ok], uv_l[ok], uv_r[ok]


BUILDS = {"misaligned": lambda: load_rig("misaligned"), "default": default_rig,
          **{f"random{s}": (lambda s=s: random_build(s)[0]) for s in (3, 4, 5)}}


@pytest.mark.parametrize("name", sorted(BUILDS))
def test_twins_share_a_rectified_row_over_the_working_range(name):
    rig = BUILDS[name]()
    rect = rectify(rig)
    pts, left, right = twins(rig, seed=len(name))
    assert len(pts) > 1000
    vl = rect.to_rectified(left, "left")
    vr = rect.to_rectified(right, "right")
    assert np.abs(vl[:, 1] - vr[:, 1]).max() <= 0.05           # the required bound, px
    assert rect.residual_px <= 0.05
    if not rig.as_designed:
        assert np.abs(left[:, 1] - right[:, 1]).max() > 5     # ... where the raw rows are far apart
    # the disparity decreases with depth (monotonic), and a point's rectified coordinates are the
    # pinhole projection from its view's centre: depth from disparity, with the fitted baseline
    d = vl[:, 0] - vr[:, 0]
    assert np.all(d > 0)
    q = (pts - rect.centres_mm["right"]) @ rect.rotation.T
    z_rect = rect.camera_matrix[0, 0] * rect.baseline_mm / d
    assert np.median(np.abs(z_rect - q[:, 2]) / q[:, 2]) < 2e-3


def test_a_plate_free_paper_rig_rectifies_to_the_textbook_pair():
    """No plate, no errors, no distortion: the identity rotation, O1 and O2 of the paper (III.2), and
    disparity = f b / (Z + b/2) / pitch (eq. 12 inverted)."""
    rig = default_rig().replace(plate_thickness_mm=0.0)
    rect = rectify(rig)
    np.testing.assert_allclose(rect.rotation, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(rect.centres_mm["left"], [-50.0, 0.0, -50.0], atol=1e-6)
    np.testing.assert_allclose(rect.centres_mm["right"], [50.0, 0.0, -50.0], atol=1e-9)
    pts, left, right = twins(rig, seed=7, n=500)
    d = rect.to_rectified(left, "left")[:, 0] - rect.to_rectified(right, "right")[:, 0]
    np.testing.assert_allclose(d, 11.3 * 100.0 / (pts[:, 2] + 50.0) / 0.01, atol=1e-6)


@pytest.mark.parametrize("view", ["left", "right"])
def test_maps_and_inverse_agree_with_the_exact_optics(view):
    rig = load_rig("misaligned")
    rect = rectify(rig)
    mu, mv = rect.maps(view)
    assert mu.shape == (rect.size_px[1], rect.size_px[0]) and mu.dtype == np.float32
    rng = np.random.default_rng(1)
    w, h = rect.size_px
    q = np.column_stack([rng.uniform(0, w - 1, 2000), rng.uniform(0, h - 1, 2000)])
    exact = rect.to_complex(q, view)
    interp = np.column_stack([map_coordinates(m, [q[:, 1], q[:, 0]], order=1) for m in (mu, mv)])
    inside = np.all(np.isfinite(exact), axis=1) & (exact[:, 0] > 2) & (exact[:, 0] < rig.camera.image_size_px[0] - 3) \
        & (exact[:, 1] > 2) & (exact[:, 1] < rig.camera.image_size_px[1] - 3)
    # away from the field's border (where bilinear reading mixes in the -1 of "outside")
    near_edge = np.zeros(len(q), bool)
    for du in (-1, 0, 1, 2):
        for dv in (-1, 0, 1, 2):
            ui = np.clip(q[:, 0].astype(int) + du, 0, w - 1)
            vi = np.clip(q[:, 1].astype(int) + dv, 0, h - 1)
            near_edge |= mu[vi, ui] < 0
    ok = inside & ~near_edge
    assert ok.sum() > 1000
    assert np.abs(interp[ok] - exact[ok]).max() < 2e-3
    np.testing.assert_allclose(rect.to_rectified(exact[ok], view), q[ok], atol=1e-8)
    # the whole camera field lands inside the rectified image
    cw, ch = rig.camera.image_size_px
    corners = np.array([[0, 0], [cw - 1, 0], [0, ch - 1], [cw - 1, ch - 1]], float)
    r = rect.to_rectified(corners, view)
    assert np.all((r >= 0) & (r <= np.array(rect.size_px) - 1))


def test_remap_moves_a_dot_to_its_rectified_place():
    """A Gaussian dot drawn at a left-view pixel of the complex image lands, after the left remap, where
    to_rectified puts it (centroid within 0.05 px)."""
    rig = load_rig("misaligned")
    rect = rectify(rig)
    w, h = rig.camera.image_size_px
    c = np.array([[180.3, 120.7]])
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    img = np.exp(-((u - c[0, 0]) ** 2 + (v - c[0, 1]) ** 2) / (2 * 2.0 ** 2)).astype(np.float32)
    out = rect.remap(img, "left")
    uu, vv = np.meshgrid(np.arange(out.shape[1]), np.arange(out.shape[0]))
    centroid = np.array([(out * uu).sum(), (out * vv).sum()]) / out.sum()
    np.testing.assert_allclose(centroid, rect.to_rectified(c, "left")[0], atol=0.05)


def test_cache_and_errors():
    rig = load_rig("misaligned")
    assert rectify(rig) is rectify(rig)
    assert needs_rectification(rig) and not needs_rectification(default_rig())
    assert needs_rectification(default_rig().replace(distortion=(-0.1, 0, 0, 0, 0)))
    with pytest.raises(ValueError, match="view must be 'left' or 'right'"):
        rectify(rig).to_rectified([[1.0, 2.0]], "centre")
    with pytest.raises(ValueError, match="0 < near < far"):
        rectify(rig, 900.0, 500.0)


def test_memory_is_shared_and_seeded():
    """rectify keeps one rectification per rig and range (keyword or positional, int or float range);
    remember seeds it with one read back from a store unless one is kept already; preload_maps takes only
    maps of the rectified grid's shape, float32."""
    import dataclasses

    from psvs.optics.rectify import forget, remember, remembered
    rig = load_rig("misaligned")
    forget()
    assert remembered(rig) is None
    rect = rectify(rig)
    assert rectify(rig, 400, 1200) is rect and remembered(rig, 400.0, 1200.0) is rect
    forget()
    assert remember(rect) is rect and rectify(rig) is rect
    assert remember(dataclasses.replace(rect)) is rect          # another object of the same key: the kept one
    w, h = rect.size_px
    with pytest.raises(ValueError, match=rf"map_u must be a float32 array of shape \({h}, {w}\), got float64"):
        rect.preload_maps("left", np.zeros((h, w)), np.zeros((h, w), np.float32))
    with pytest.raises(ValueError, match=rf"map_v must be a float32 array of shape \({h}, {w}\)"):
        rect.preload_maps("left", np.zeros((h, w), np.float32), np.zeros((h, w - 1), np.float32))
    mu, mv = rect.maps("right")
    rect.preload_maps("right", mu.copy(), mv.copy())
    assert np.array_equal(rect.maps("right")[0], mu)
