"""A build's rectification, remaps and depth table made once per rig content (psvs.dense.rig_cache): read
back from the cache folder by value (the same arrays as computed, without computing them), never for
another rig's values, recomputed over a damaged file, and no cache at all (but the same answers) where the
folder cannot be written. Each test has its own folder (the session's is tests/conftest.py's)."""
import os
import threading

import numpy as np
import pytest

from psvs import default_rig
from psvs._cache import cache_dir
from psvs.dense import rig_cache
from psvs.dense.rig_cache import depth_table, forget, nearest_inside, rectification, rig_key
from psvs.io.params import load_rig, save_rig
from psvs.optics.rectify import VIEWS, rectify
from psvs.optics.rig import Calibration, MirrorError, MirrorExtent

NEAR_MM, FAR_MM = 500.0, 1300.0       # not the default range: the files are this test module's own


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """An empty cache folder for the test, and no rectification in memory before or after it."""
    monkeypatch.setenv("PSVS_CACHE_DIR", str(tmp_path / "cache"))
    forget()
    yield tmp_path / "cache"
    forget()


@pytest.fixture
def work(monkeypatch):
    """Counts of the fits, remaps (per view) and table builds done."""
    import psvs.optics.rectify as rectify_module
    calls = {"fit": 0, "maps": 0, "table": 0}
    fit, build, maps = rig_cache.rectify, rig_cache.build_depth_table, rectify_module._build_maps

    def counted_maps(*a, **k):
        calls["maps"] += 1
        return maps(*a, **k)

    def counted_fit(*a, **k):
        calls["fit"] += 1
        return fit(*a, **k)

    def counted_build(*a, **k):
        calls["table"] += 1
        return build(*a, **k)
    monkeypatch.setattr(rig_cache, "rectify", counted_fit)
    monkeypatch.setattr(rig_cache, "build_depth_table", counted_build)
    monkeypatch.setattr(rectify_module, "_build_maps", counted_maps)
    return calls


def values(rig):
    """Everything the cache holds for ``rig`` over NEAR..FAR, as arrays (computing what is missing)."""
    rect = rectification(rig, NEAR_MM, FAR_MM)
    table = depth_table(rect)
    out = {"rotation": rect.rotation, "camera_matrix": rect.camera_matrix, "z_ref_mm": rect.z_ref_mm,
           "size_px": np.array(rect.size_px), "residual_px": rect.residual_px, "step_px": table.step_px,
           "slopes": table.slopes, "cells_left": table.cells_left, "cells_right": table.cells_right,
           "disparity_px": np.array(table.disparity_px), "max_error_mm": table.max_error_mm}
    for view in VIEWS:
        out[f"centre_{view}"] = rect.centres_mm[view]
        out[f"map_u_{view}"], out[f"map_v_{view}"] = rect.maps(view)
        out[f"nearest_{view}"] = nearest_inside(rect, view)
    return rect, out


def assert_same(a: dict, b: dict):
    assert a.keys() == b.keys()
    for k in a:
        x, y = np.asarray(a[k]), np.asarray(b[k])
        assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y), k


def test_round_trip_by_value(folder, work):
    rig = load_rig("misaligned")
    rect, computed = values(rig)
    assert work == {"fit": 1, "maps": 2, "table": 1}
    files = sorted(p.name.split(".", 1)[1] for p in (folder / "builds").iterdir())
    assert files == ["depth.npz", "rect.npz"]
    forget()
    again, read = values(rig)
    assert again is not rect and work == {"fit": 1, "maps": 2, "table": 1}      # read back, nothing computed
    assert_same(computed, read)
    assert rectify(rig, NEAR_MM, FAR_MM) is again                    # one object for every caller
    assert rectification(rig, NEAR_MM, FAR_MM) is again and depth_table(again) is depth_table(again)


def test_a_changed_rig_file_misses(folder, work, tmp_path):
    """The same path with new values: a new entry, never the old one."""
    path = tmp_path / "build.toml"
    rig = load_rig("misaligned")
    save_rig(rig, path)
    _, first = values(load_rig(path))
    forget()
    changed = rig.with_errors({"m3": MirrorError((rig.mirrors.m3_error.tilt_rad[0] + 1e-4, 0.0), 0.1)})
    save_rig(changed, path)
    _, second = values(load_rig(path))
    assert work == {"fit": 2, "maps": 4, "table": 2}
    assert not np.array_equal(first["map_u_left"], second["map_u_left"])
    assert len(list((folder / "builds").iterdir())) == 4


@pytest.mark.parametrize("change", [
    {"focal_length_mm": 11.4130001}, {"distortion": (-0.2, 0.45, 0.0012, -0.0009, -0.0300001)},
    {"image_size_px": (640, 481)}, {"principal_point_px": (324.3, 236.61)}, {"baseline_mm": 100.001},
    {"plate_thickness_mm": 3.001}, {"refractive_index": 1.5201}, {"box_rotation_rad": (0.0021, -0.0035, 0.0026)},
    {"m2_error": MirrorError((0.001, 0.0), 0.0)}, {"m1_extent": MirrorExtent((-10.0, 10.0), (-8.0, 8.0))},
])
def test_every_optical_value_is_in_the_key(change):
    rig = load_rig("misaligned")
    assert rig_key(rig.replace(**change), 400.0, 1200.0) != rig_key(rig, 400.0, 1200.0)


def test_the_key_is_the_values_and_the_range():
    rig = load_rig("misaligned")
    key = rig_key(rig, 400.0, 1200.0)
    assert len(key) == 64 and rig_key(load_rig("misaligned"), 400, 1200) == key
    calibrated = type(rig)(rig.camera, rig.mirrors, Calibration(0.1, 0.1, 0.1, 12))
    assert rig_key(calibrated, 400.0, 1200.0) == key                 # how it was found changes no ray
    assert rig_key(rig, 400.0, 1199.0) != key and rig_key(rig, 401.0, 1200.0) != key


@pytest.mark.parametrize("damage", ["truncated", "flipped", "header length", "garbage", "empty", "other key", "pipe"])
@pytest.mark.parametrize("kind", ["rect", "depth"])
def test_a_damaged_file_is_recomputed_and_rewritten(folder, work, damage, kind):
    rig = load_rig("misaligned")
    _, computed = values(rig)
    path = folder / "builds" / f"{rig_key(rig, NEAR_MM, FAR_MM)}.{kind}.npz"
    data = path.read_bytes()
    if damage == "truncated":
        path.write_bytes(data[:len(data) // 2])
    elif damage == "flipped":                      # one bit in the middle of an array's bytes
        k = len(data) // 2
        path.write_bytes(data[:k] + bytes([data[k] ^ 0x10]) + data[k + 1:])
    elif damage == "header length":                # one bit of an array's .npy header length (trial 48: the
        at = [k for k in range(len(data)) if data.startswith(b"\x93NUMPY\x01\x00", k)]     # array read a few
        k = at[len(at) // 2] + 8                   # bytes early, its member not read to its end, unchecked
        assert data[k] & 0x04
        path.write_bytes(data[:k] + bytes([data[k] ^ 0x04]) + data[k + 1:])
    elif damage == "pipe":                         # a read would wait for a writer
        path.unlink()
        os.mkfifo(path)
    elif damage == "garbage":
        path.write_bytes(b"PK\x03\x04 not a cache file")
    elif damage == "empty":
        path.write_bytes(b"")
    else:                                          # a sound file of another rig, renamed
        other = rig.replace(baseline_mm=101.0)
        forget()
        values(other)
        path.write_bytes((folder / "builds" / f"{rig_key(other, NEAR_MM, FAR_MM)}.{kind}.npz").read_bytes())
    before = dict(work)
    forget()
    _, again = values(rig)
    assert_same(computed, again)
    more = {"rect": {"fit": 1, "maps": 2, "table": 0}, "depth": {"fit": 0, "maps": 0, "table": 1}}[kind]
    assert work == {k: before[k] + more[k] for k in work}
    forget()
    done = dict(work)
    _, read = values(rig)                           # rewritten: read back now
    assert work == done
    assert_same(computed, read)


def test_an_unwritable_folder_means_no_cache(tmp_path, monkeypatch, work):
    """A file where the folder should be: nothing stored, the same answers, no error."""
    (tmp_path / "file").write_text("not a folder")
    monkeypatch.setenv("PSVS_CACHE_DIR", str(tmp_path / "file" / "cache"))
    forget()
    rig = load_rig("misaligned")
    _, first = values(rig)
    forget()
    _, second = values(rig)
    assert work == {"fit": 2, "maps": 4, "table": 2}
    assert_same(first, second)
    forget()


def test_memory_and_threads(folder, work):
    """One fit and one table per rig in a process, shared by every caller and thread; none on the paper's
    geometry."""
    rig = load_rig("misaligned")
    got = []
    threads = [threading.Thread(target=lambda: got.append(depth_table(rectification(rig, NEAR_MM, FAR_MM))))
               for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert work == {"fit": 1, "maps": 2, "table": 1} and len(got) == 4 and all(t is got[0] for t in got)
    assert rectification(default_rig()) is None


def test_the_folder_keeps_the_files_used_last(folder, monkeypatch):
    monkeypatch.setattr(rig_cache, "KEEP_FILES", 3)
    rig = load_rig("misaligned")
    for far in (1100.0, 1200.0, 1300.0):
        depth_table(rectification(rig, NEAR_MM, far))
    names = sorted(p.name for p in (folder / "builds").iterdir())
    assert len(names) == 3 and f"{rig_key(rig, NEAR_MM, 1300.0)}.rect.npz" in names


def test_where_the_folder_is(monkeypatch, tmp_path):
    monkeypatch.setenv("PSVS_CACHE_DIR", str(tmp_path / "own"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "own"
    monkeypatch.delenv("PSVS_CACHE_DIR")
    assert cache_dir() == tmp_path / "xdg" / "psvs"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/path")             # not absolute: ignored (XDG's rule)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "psvs"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_dir() == tmp_path / "home" / ".cache" / "psvs"


def test_the_filled_maps_resample_as_the_remap_and_its_fill_in(folder):
    """filled_maps: one remap through them is the remap of a view followed by its nearest-inside fill-in
    (rectified_images before them), to float32 rounding (OpenCV's vector and scalar paths), on a build whose
    views' fields leave the grid's corners outside; and a band of their rows is that band of the whole grid."""
    import cv2

    from psvs.dense.build import rectified_images
    from psvs.dense.rig_cache import filled_maps
    rig = load_rig("misaligned")
    rect = rectification(rig, NEAR_MM, FAR_MM)
    img = np.random.default_rng(0).uniform(0, 255, rig.camera.image_size_px[::-1]).astype(np.float32)
    grids = rectified_images(img, rect)
    for view, grid in zip(VIEWS, grids, strict=True):
        index = nearest_inside(rect, view)
        assert (index != np.arange(index.size).reshape(index.shape)).any()      # some pixels are filled in
        np.testing.assert_allclose(grid, np.take(rect.remap(img, view), index), rtol=0, atol=1e-3)
        mu, mv = filled_maps(rect, view)
        band = cv2.remap(img, mu[100:140], mv[100:140], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        np.testing.assert_allclose(band, grid[100:140], rtol=0, atol=1e-3)
