"""The depth table of a build (psvs.dense.depth_table) against the exact ray trace it replaces: the same
pairs answered, and the same points within 0.01 mm in X, Y and Z, on many random pixels and disparities over
the working range, on the shipped builds, a random build, a build whose mirrors vignette part of the field,
and working ranges other than the default. Both references are computed here without the table: the path
``rig_cloud`` took before it (each left-grid pixel and its twin mapped back through the remaps, then
triangulated with the exact model) and the strictly exact one (mapped back with to_complex).

Where a mirror vignettes the field inside the sensor, the remaps themselves are off near that edge (their
bicubic spline runs over nodes no ray reaches, filled with their neighbours' values: up to 0.6 px on the
vignetting build, 10 mm at 1 m), so there the old path is not the reference: the pairs the table answers
are held to the strictly exact model, those it leaves to the old path (its cells at the field's edge) are
the old path's, and the pairs answered are the old path's."""
import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from psvs.dense.build import RigDense, rig_cloud, rig_depth
from psvs.dense.depth_table import (
    CHECK_MM,
    SPARSE_SHARE,
    DepthTable,
    build_depth_table,
    exact_points,
    table_cloud,
    table_depth,
    table_points,
    table_range,
)
from psvs.dense.disparity import DenseResult
from psvs.dense.rig_cache import depth_table
from psvs.io.params import load_rig
from psvs.measure.triangulate import triangulate
from psvs.optics.mirrors import front_z_mm
from psvs.optics.rectify import rectify
from tests.support.rig_draws import random_build

TOL_MM = 0.01           # the required agreement, X, Y and Z


def vignetting_build():
    """The clear design (finite mirrors) with the misaligned build's errors, M3 and M4 cut to 80 and 85 %:
    a quarter of the left view's and a sixth of the right view's pixels are vignetted."""
    clear, mis = load_rig("clear"), load_rig("misaligned").mirrors
    rig = clear.with_errors({k: mis.error(k) for k in ("m1", "m2", "m3", "m4")})
    rig = rig.replace(box_rotation_rad=mis.box_rotation_rad)
    return rig.replace(m3_extent=rig.mirrors.m3_extent.scaled(0.8), m4_extent=rig.mirrors.m4_extent.scaled(0.85))


BUILDS = {"misaligned": lambda: load_rig("misaligned"), "mv1440_misaligned": lambda: load_rig("mv1440_misaligned"),
          "random3": lambda: random_build(3)[0], "vignetting": vignetting_build}


def samples(rect, seed, n=20000):
    """Left-grid pixels (N, 2) and disparities (N,) px: uniform over the grid, and as many within 12 px of
    the edge of the left view's field or with their twin within 12 px of the right view's; disparities
    uniform in 1/d over the table's range (the working range's, with its margins)."""
    rng = np.random.default_rng(seed)
    w, h = rect.size_px
    lo, hi = table_range(rect)
    d = 1.0 / rng.uniform(1.0 / hi, 1.0 / lo, 3 * n)
    uv = [np.column_stack([rng.integers(0, w, n), rng.integers(0, h, n)])]
    for k, view in enumerate(("left", "right")):
        outside = rect.maps(view)[0] < 0
        near = np.argwhere((distance_transform_edt(~outside) <= 12) & ~outside)[:, ::-1]     # (u', v') inside
        pick = near[rng.integers(0, len(near), n)].astype(float)
        if view == "right":
            pick[:, 0] += d[(k + 1) * n:(k + 2) * n]      # the left pixel whose twin lies there
        uv.append(pick)
    return np.concatenate(uv).astype(float), d


@pytest.mark.parametrize("name, near_mm, far_mm", [("misaligned", 400.0, 1200.0), ("misaligned", 300.0, 2500.0),
                                                   ("mv1440_misaligned", 550.0, 1100.0), ("random3", 400.0, 1200.0),
                                                   ("random3", 600.0, 1500.0), ("vignetting", 400.0, 1200.0)])
def test_table_agrees_with_the_exact_trace(name, near_mm, far_mm):
    rig = BUILDS[name]()
    rect = rectify(rig, near_mm, far_mm)
    table = depth_table(rect)
    assert table.max_error_mm <= CHECK_MM
    uv, d = samples(rect, seed=len(name) + int(near_mm))
    got = table_points(table, rect, uv, d)
    before = exact_points(rect, uv, d)                      # rig_cloud's path before the table
    np.testing.assert_array_equal(got.valid, before.valid)  # the same pairs answered, the border included
    assert got.valid.sum() > 20000
    assert np.isnan(got.points_mm[~got.valid]).all()
    exact = exact_points(rect, uv, d, mapping="exact")      # the strictly exact model
    both = got.valid & exact.valid
    if name == "vignetting":                                # the old path's own pairs are left out (above)
        both &= ~np.all(got.points_mm == before.points_mm, axis=1)
    else:
        err = np.abs(got.points_mm[got.valid] - before.points_mm[got.valid])
        assert err.max() <= TOL_MM, err.max(axis=0)
    assert both.sum() > 20000
    err = np.abs(got.points_mm[both] - exact.points_mm[both])
    assert err.max() <= TOL_MM, err.max(axis=0)


def test_what_the_exact_model_rejects_is_nan():
    """A twin left of the right view's field, a pixel off the left view's, a disparity of a point inside the
    mirror box (its twin leaves the field), a negative one (rays that meet behind the rig) and NaN give no
    point, as on the exact path; a disparity beyond the table's range is answered by the exact path itself."""
    rect = rectify(load_rig("misaligned"))
    table = depth_table(rect)
    w, h = rect.size_px
    lo, hi = table.disparity_px
    inside_box = 1.1 * rect.camera_matrix[0, 0] * rect.baseline_mm / front_z_mm(rect.rig)   # Z ~ front_z / 1.1
    uv = np.array([[5.0, h / 2], [w / 2, -3.0], [w / 2, h / 2], [w / 2, h / 2], [w / 2, h / 2], [w / 2, h / 2],
                   [w / 2, h / 2]])
    d = np.array([lo + 1, lo + 1, inside_box, -20.0, np.nan, hi + 30.0, (lo + hi) / 2])
    got = table_points(table, rect, uv, d)
    before = exact_points(rect, uv, d)
    np.testing.assert_array_equal(got.valid, [False] * 5 + [True, True])
    np.testing.assert_array_equal(got.valid, before.valid)
    assert np.array_equal(got.points_mm[5], before.points_mm[5])          # beyond the table: the exact path
    assert np.abs(got.points_mm[6] - before.points_mm[6]).max() <= TOL_MM


def test_rig_cloud_on_a_build_goes_through_the_table(monkeypatch):
    """rig_cloud keeps its meaning (points, left-grid pixels, depth on the grid, NaN where no point) and, with
    the exact model, its numbers within 0.01 mm: a slanted plane's disparities over the whole grid."""
    rig = load_rig("misaligned")
    rect = rectify(rig)
    w, h = rect.size_px
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    zc = 0.5 * (rect.centres_mm["left"] + rect.centres_mm["right"]) @ rect.rotation[2]
    z = 700.0 + 0.4 * (u - w / 2)                            # a plane slanted about the vertical, mm
    d = (rect.camera_matrix[0, 0] * rect.baseline_mm / (z - zc)).astype(np.float32)
    res = DenseResult(d, d, np.ones_like(d), np.ones_like(d), (1.0, 300.0))
    dense = RigDense(res, rect, np.zeros_like(d))
    calls = []
    monkeypatch.setattr("psvs.dense.build.table_cloud", lambda *a: calls.append(1) or table_cloud(*a))
    cloud = rig_cloud(dense, rig)
    assert calls == [1]
    keep = np.isfinite(d) & (d > 0)
    vv, uu = np.nonzero(keep)
    before = exact_points(rect, np.column_stack([uu, vv]).astype(float), d[vv, uu].astype(float))
    np.testing.assert_array_equal(cloud.pixels, np.column_stack([uu, vv])[before.valid])
    np.testing.assert_array_equal(np.isfinite(cloud.depth_mm[vv, uu]), before.valid)
    assert np.abs(cloud.points_mm - before.points_mm[before.valid]).max() <= TOL_MM
    np.testing.assert_array_equal(cloud.depth_mm[vv[before.valid], uu[before.valid]], cloud.points_mm[:, 2])
    assert len(cloud.points_mm) > 0.5 * keep.sum()
    np.testing.assert_array_equal(rig_depth(dense, rig), cloud.depth_mm)       # the depth map alone: the same
    # another model, or another rig than the rectification's: the exact path, as before
    refr = rig_cloud(dense, rig, model="refraction", mask=keep & (u % 7 == 0))
    ref = exact_points(rect, np.column_stack([uu, vv]).astype(float), d[vv, uu].astype(float), "refraction")
    sub = (uu % 7 == 0) & ref.valid
    np.testing.assert_allclose(refr.points_mm, ref.points_mm[sub], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(rig_depth(dense, rig, model="refraction", mask=keep & (u % 7 == 0)),
                                  refr.depth_mm)
    assert calls == [1]


def test_the_map_pass_gives_table_points_numbers():
    """table_cloud (one pass over a map, or a sparse mask's pixels listed) against table_points on the same
    pixels: the same points bit for bit, in row order, with NaN, 0, negative, masked-out and beyond-the-table
    disparities (the exact path's)."""
    assert 0.1 < SPARSE_SHARE < 0.3
    rect = rectify(load_rig("misaligned"))
    table = depth_table(rect)
    w, h = rect.size_px
    lo, hi = table.disparity_px
    rng = np.random.default_rng(7)
    d = rng.uniform(lo, hi, (h, w)).astype(np.float32)
    d[rng.random((h, w)) < 0.1] = np.nan
    d[rng.random((h, w)) < 0.05] = 0.0
    d[rng.random((h, w)) < 0.05] = -4.0
    d[rng.random((h, w)) < 0.02] = hi + 20.0               # beyond the table: the exact path answers
    # no mask and a dense one: the one-pass kernel; a sparse one (a live loop's grid): the listed pixels
    for mask in (None, rng.random((h, w)) < 0.3, rng.random((h, w)) < 0.1):
        keep = np.isfinite(d) & (d > 0) & (True if mask is None else mask)
        vv, uu = np.nonzero(keep)
        uv = np.column_stack([uu, vv]).astype(float)
        want = table_points(table, rect, uv, d[vv, uu].astype(np.float64))
        pts, pixels, depth = table_cloud(table, rect, d, mask)
        np.testing.assert_array_equal(pts, want.points_mm[want.valid])
        np.testing.assert_array_equal(pixels, uv[want.valid])
        expect = np.full((h, w), np.nan)
        expect[vv[want.valid], uu[want.valid]] = want.points_mm[want.valid, 2]
        np.testing.assert_array_equal(depth, expect)
        np.testing.assert_array_equal(table_depth(table, rect, d, mask), expect)      # Z alone: the same numbers
        assert ((d[vv, uu] > hi) & want.valid).sum() > 0.01 * keep.sum() and want.valid.sum() > 0.6 * keep.sum()
    with pytest.raises(ValueError, match="must be \\(H, W\\)"):
        table_cloud(table, rect, d[0])
    with pytest.raises(ValueError, match="mask \\(3, 3\\) must have the map's shape"):
        table_cloud(table, rect, d, np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="must be \\(H, W\\)"):
        table_depth(table, rect, d[0])
    with pytest.raises(ValueError, match="mask \\(3, 3\\) must have the map's shape"):
        table_depth(table, rect, d, np.ones((3, 3), bool))


def test_exact_points_is_the_old_path():
    """exact_points maps back through the remaps and triangulates: triangulate's numbers exactly."""
    rig = load_rig("misaligned")
    rect = rectify(rig)
    uv = np.array([[300.0, 250.0], [320.0, 200.0]])
    d = np.array([120.0, 150.5])
    left = rect.lookup(uv, "left")
    right = rect.lookup(np.column_stack([uv[:, 0] - d, uv[:, 1]]), "right")
    np.testing.assert_array_equal(exact_points(rect, uv, d).points_mm,
                                  triangulate(left, right, rig, model="exact").points_mm)


def test_a_given_step_is_kept_and_the_default_is_checked():
    rect = rectify(load_rig("misaligned"))
    coarse = build_depth_table(rect, step_px=64)
    assert coarse.step_px == 64 and coarse.max_error_mm > CHECK_MM       # the check measures, it does not hide
    fine = build_depth_table(rect)
    assert fine.step_px <= 8 and fine.max_error_mm <= CHECK_MM
    assert fine.slopes.shape[2] == 2 and fine.cells_left.shape == tuple(s - 1 for s in fine.slopes.shape[:2])


def test_errors():
    rect = rectify(load_rig("misaligned"))
    table = depth_table(rect)
    with pytest.raises(ValueError, match=r"disparity_px must have shape \(2,\)"):
        table_points(table, rect, np.zeros((2, 2)), np.zeros(3))
    with pytest.raises(ValueError, match="built for another rectification"):
        table_points(DepthTable(table.step_px * 2, table.slopes, table.cells_left, table.cells_right,
                                table.disparity_px, 0.0), rect, np.zeros((1, 2)), np.ones(1))
    with pytest.raises(ValueError, match="uv_rect_px"):
        table_points(table, rect, np.zeros((2, 3)), np.zeros(2))
    with pytest.raises(ValueError, match="0 < low < high"):
        build_depth_table(rect, disparity_px=(50.0, 10.0))
    with pytest.raises(ValueError, match="step_px must be an integer >= 1, got 0"):
        build_depth_table(rect, step_px=0)
    with pytest.raises(ValueError, match="mapping must be 'lookup' or 'exact', got 'remap'"):
        exact_points(rect, np.zeros((1, 2)), np.ones(1), mapping="remap")
