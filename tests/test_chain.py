"""The whole chain through the files each command writes, as a user runs it:
sweep-views -> calibrate -> measure -> match -> triangulate, and simulate -> disparity, every file read back
by an independent reader (tomllib, json, csv, plyfile, NumPy, OpenCV) and compared by value."""
import csv
import io
import json
import tomllib
from contextlib import redirect_stderr, redirect_stdout

import cv2
import numpy as np
import pytest
from plyfile import PlyData

from psvs import default_rig
from psvs.cli.main import main
from psvs.dense.build import RigDense, rig_cloud
from psvs.dense.disparity import DenseResult
from psvs.io.params import load_rig, save_rig
from psvs.optics.rectify import rectify

#: long end-to-end runs: the README's test command runs them; .ci/latest (newest releases) does not
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A robot sweep rendered through the default rig, calibrated from a wrong guess (f 2 % long, b 5 mm
    long, plate 2 mm): the rig file the rest of the chain uses."""
    folder = tmp_path_factory.mktemp("chain")
    guess = default_rig().replace(focal_length_mm=11.53, baseline_mm=105.0, plate_thickness_mm=2.0)
    save_rig(guess, folder / "guess.toml")
    psvs("sweep-views", str(folder / "sweep"), "--rig", "default", "--step-mm", "75")
    rows = list(csv.DictReader((folder / "sweep" / "sweep.csv").open()))
    assert [float(r["position_mm"]) for r in rows] == pytest.approx(np.arange(425, 1176, 75) + 312.7, abs=1e-9)
    assert all(cv2.imread(str(folder / "sweep" / r["image"]), cv2.IMREAD_UNCHANGED).shape == (480, 640)
               for r in rows)
    psvs("calibrate", str(folder / "sweep"), "--rig", str(folder / "guess.toml"),
                  "-o", str(folder / "rig.toml"))
    return folder


def psvs(*argv) -> str:
    """Run ``psvs ARGV`` in-process; assert exit status 0; return what it printed on stdout."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main([str(a) for a in argv])
    assert code == 0, err.getvalue()
    return out.getvalue()


def test_calibrated_rig_file_reads_back(calibrated):
    data = tomllib.loads((calibrated / "rig.toml").read_text())
    rig = load_rig(calibrated / "rig.toml")
    assert data["camera"]["focal_length_mm"] == rig.camera.focal_length_mm
    truth = default_rig()
    assert rig.camera.focal_length_mm == pytest.approx(truth.camera.focal_length_mm, rel=2e-3)
    assert rig.mirrors.baseline_mm == pytest.approx(truth.mirrors.baseline_mm, abs=0.5)


def test_measure_with_the_calibrated_rig(calibrated, tmp_path):
    psvs("simulate", "fig9:distance_mm=680", "--rig", "default", "-o", str(tmp_path / "f9.png"))
    out = psvs("measure", "circles", tmp_path / "f9.png", "--rig", calibrated / "rig.toml", "--json")
    m = json.loads(out)
    assert m["Z_mm"] == pytest.approx(680.0, abs=1.0)
    assert m["diameter_mm"] == pytest.approx(10.0, abs=0.1)
    assert m["first_last_distance_mm"] == pytest.approx(80.0, abs=0.3)


def test_match_then_triangulate_with_the_calibrated_rig(calibrated, tmp_path):
    rig = str(calibrated / "rig.toml")
    img, js, cs, ply, pts = (tmp_path / n for n in ("f5a.png", "m.json", "m.csv", "m.ply", "p.csv"))
    psvs("simulate", "fig5a", "--rig", "default", "-o", str(img), "--seed", "2")
    psvs("match", str(img), "--rig", rig, "--auto", "-o", str(js), "--csv", str(cs), "--ply", str(ply))
    data = json.loads(js.read_text())
    assert len(data["pairs"]) == 2
    pts_json = np.concatenate([np.array(p["points_mm"], float) for p in data["pairs"]])
    left_json = np.concatenate([np.array(p["left_px"], float) for p in data["pairs"]])
    rows = list(csv.DictReader(cs.open()))
    assert len(rows) == len(pts_json)
    # the CSV holds 4 decimals (1e-4 px, 1e-4 mm): equal to the JSON's full floats within half of that
    assert np.array([[float(r["u_l"]), float(r["v_l"])] for r in rows]) == pytest.approx(left_json, abs=5.1e-5)
    xyz_csv = np.array([[float(r[k]) for k in ("X_mm", "Y_mm", "Z_mm")] for r in rows])
    assert xyz_csv == pytest.approx(pts_json, abs=5.1e-5, nan_ok=True)
    v = PlyData.read(str(ply))["vertex"]
    ok = np.all(np.isfinite(pts_json), axis=1)
    assert v.count == ok.sum()
    assert np.column_stack([v["x"], v["y"], v["z"]]) == pytest.approx(pts_json[ok], abs=1e-3)   # float32 in PLY
    # triangulate the CSV the match wrote, with the same rig and model: the same points
    psvs("triangulate", "--rig", rig, str(cs), "-o", str(pts))
    tri = list(csv.DictReader(pts.open()))
    xyz = np.array([[float(r[k]) for k in ("X_mm", "Y_mm", "Z_mm")] for r in tri])
    assert xyz[ok] == pytest.approx(pts_json[ok], abs=2e-3)   # from 4-decimal pixels: ~1e-4 px -> < 2 um
    assert np.median(pts_json[ok][:, 2]) == pytest.approx(625.0, abs=30.0)   # box 600, cylinder 650 mm


def test_disparity_with_the_calibrated_rig(calibrated, tmp_path):
    rig = str(calibrated / "rig.toml")
    img, truth, disp, conf, cloud = (tmp_path / n for n in ("t.png", "t.npz", "d.npy", "c.npy", "c.ply"))
    views = [tmp_path / "l.png", tmp_path / "r.png"]
    psvs("simulate", "textured", "--rig", "default", "-o", str(img), "--truth", str(truth))
    psvs("disparity", str(img), "--rig", rig, "--fast", "-o", str(disp), "--cloud", str(cloud),
                  "--confidence", str(conf), "--views", *map(str, views))
    d = np.load(disp)
    t = np.load(truth)
    # a rig calibrated from images is a build (its mirrors are never exactly at 45 deg): the maps are on the
    # rectified grid of its left view (docs/dense.md)
    calibrated_rig = load_rig(rig)
    rect = rectify(calibrated_rig)
    assert d.shape == rect.size_px[::-1] and d.dtype == np.float32
    assert np.isfinite(d).mean() > 0.5
    v = PlyData.read(str(cloud))["vertex"]
    dense = RigDense(DenseResult(d, d, d, d, (0.0, 0.0)), rect, d)
    # the library's triangulation of the map the CLI wrote, at the pixels it trusts (the cloud's)
    ref = rig_cloud(dense, calibrated_rig, mask=np.load(conf) > 0)
    assert v.count == len(ref.points_mm) > 0.4 * 480 * 640
    assert np.column_stack([v["x"], v["y"], v["z"]]) == pytest.approx(ref.points_mm, rel=1e-6, abs=1e-3)
    # each vertex's left pixel, back in the complex image, against the renderer's depth
    u, vv = np.rint(rect.lookup(ref.pixels, "left")).astype(int).T
    z_true = t["depth_left_mm"][vv, u]
    good = t["valid_left"][vv, u] & np.isfinite(z_true)
    assert good.sum() > 0.5 * v.count
    assert np.median(np.abs(v["z"][good] - z_true[good]) / z_true[good]) < 0.01
    for p in views:
        assert cv2.imread(str(p), cv2.IMREAD_UNCHANGED).shape == rect.size_px[::-1]
