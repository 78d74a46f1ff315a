"""Calibration export: ROS CameraInfo YAML and OpenCV FileStorage of both views, read
back by independent readers (ruamel.yaml, cv2.FileStorage) and checked against the exact optics: the
right view is a pinhole exactly, the left within the error the files state; Q gives back 3-D points."""
import cv2
import numpy as np
import pytest
from ruamel.yaml import YAML

from psvs.cli.main import main
from psvs.io.camera_info import write_calibration_files
from psvs.io.params import load_rig
from psvs.optics.pinhole_views import pinhole_views, undistort_points
from psvs.optics.project import project_points
from psvs.optics.rectify import rectify
from psvs.optics.rig import default_rig


def _points(rig, n=400, seed=0):
    rng = np.random.default_rng(seed)
    z = rng.uniform(450.0, 1100.0, n)
    pts = np.column_stack([rng.uniform(-0.15, 0.15, n) * z, rng.uniform(-0.15, 0.15, n) * z, z])
    ok = np.ones(n, bool)
    for view in ("left", "right"):
        uv, seen = project_points(pts, rig, view)
        ok &= seen & (uv[:, 0] >= 0) & (uv[:, 0] <= 639) & (uv[:, 1] >= 0) & (uv[:, 1] <= 479)
    return pts[ok]


def _read_ros(path):
    doc = YAML(typ="safe").load(path.read_text())
    m = {k: np.array(doc[k]["data"], float).reshape(doc[k]["rows"], doc[k]["cols"])
         for k in ("camera_matrix", "distortion_coefficients", "rectification_matrix", "projection_matrix")}
    return doc, m


@pytest.fixture(scope="module", params=["default", "misaligned"])
def exported(request, tmp_path_factory):
    rig = default_rig() if request.param == "default" else load_rig(request.param)
    views = pinhole_views(rig, 400.0, 1200.0)
    folder = tmp_path_factory.mktemp(request.param)
    write_calibration_files(folder, views, 400.0, 1200.0, request.param)
    return rig, views, folder


def test_ros_files_read_back_by_value(exported):
    rig, views, folder = exported
    for name, view in views.items():
        doc, m = _read_ros(folder / f"{name}.yaml")
        assert (doc["image_width"], doc["image_height"]) == rig.camera.image_size_px
        assert doc["camera_name"] == f"psvs_{name}" and doc["distortion_model"] == "plumb_bob"
        assert np.array_equal(m["camera_matrix"], view.K)
        assert np.array_equal(m["distortion_coefficients"][0], view.D)
        assert np.array_equal(m["rectification_matrix"], view.R)
        P = view.P.copy()
        P[:, 3] /= 1000.0                 # ROS: Tx in metres
        assert np.array_equal(m["projection_matrix"], P)
    # the right camera one baseline along x': Tx = -f' b (m; b about the rig's 100 mm, the plate moving the
    # left view's centre by about a millimetre)
    _, m = _read_ros(folder / "right.yaml")
    b_m = -m["projection_matrix"][0, 3] / m["projection_matrix"][0, 0]
    assert b_m == pytest.approx(rig.mirrors.baseline_mm / 1000.0, rel=0.02)


def test_opencv_file_reads_back_by_value(exported):
    rig, views, folder = exported
    fs = cv2.FileStorage(str(folder / "stereo.yml"), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    for k, name in ((1, "left"), (2, "right")):
        v = views[name]
        for key, want in ((f"K{k}", v.K), (f"D{k}", v.D.reshape(1, -1)), (f"R{k}", v.R), (f"P{k}", v.P),
                          (f"rotation_in_rig{k}", v.rotation), (f"centre_in_rig{k}", v.centre_mm.reshape(3, 1))):
            assert np.allclose(fs.getNode(key).mat(), want, rtol=1e-15, atol=1e-12), key
    assert int(fs.getNode("image_width").real()) == rig.camera.image_size_px[0]
    assert fs.getNode("near_mm").real() == 400.0 and fs.getNode("far_mm").real() == 1200.0
    # R, T: the right view camera's pose relative to the left, X_2 = R X_1 + T
    R, T = fs.getNode("R").mat(), fs.getNode("T").mat().ravel()
    X = _points(rig, 20)
    left, right = views["left"], views["right"]
    X1 = (X - left.centre_mm) @ left.rotation
    X2 = (X - right.centre_mm) @ right.rotation
    assert np.allclose(X1 @ R.T + T, X2, atol=1e-9)
    fs.release()


def test_right_view_is_exactly_a_pinhole_and_left_within_its_stated_error(exported):
    """cv2.projectPoints with the files' K, D and each view camera's pose against psvs's exact projection;
    cv2.undistortPoints with R, P against the exact rectified coordinates."""
    rig, views, _ = exported
    X = _points(rig)
    rect = rectify(rig, 400.0, 1200.0)
    for name, v in views.items():
        exact, _ = project_points(X, rig, name)
        rvec, _ = cv2.Rodrigues(v.rotation.T)
        tvec = -v.rotation.T @ v.centre_mm
        model = cv2.projectPoints(X.reshape(-1, 1, 3), rvec, tvec, v.K, v.D)[0].reshape(-1, 2)
        err = np.abs(model - exact).max()
        rect_model = undistort_points(exact, v.K, v.D, v.R, v.P)  # OpenCV, either major version
        rect_err = np.abs(rect_model - rect.to_rectified(exact, name)).max(axis=0)
        if name == "right":
            assert err < 1e-6 and rect_err.max() < 1e-6
        else:
            # the plate: not central, but within the error the file states (<= 0.5 px on a 3 mm plate)
            assert np.all(rect_err <= np.array(v.error_px) + 0.02) and max(v.error_px) < 0.6
            assert err < 1.0


def test_q_gives_back_the_points(exported):
    """Disparity in the rectified coordinates -> Q -> the left rectified frame -> frame C (the files' own
    R1 and the left camera's pose): the points come back to within 0.1 % of their depth."""
    rig, views, folder = exported
    fs = cv2.FileStorage(str(folder / "stereo.yml"), cv2.FILE_STORAGE_READ)
    Q, R1 = fs.getNode("Q").mat(), fs.getNode("R1").mat()
    rot1, c1 = fs.getNode("rotation_in_rig1").mat(), fs.getNode("centre_in_rig1").mat().ravel()
    fs.release()
    X = _points(rig, seed=1)
    rect = rectify(rig, 400.0, 1200.0)
    ul = rect.to_rectified(project_points(X, rig, "left")[0], "left")
    ur = rect.to_rectified(project_points(X, rig, "right")[0], "right")
    h = np.column_stack([ul, ul[:, 0] - ur[:, 0], np.ones(len(X))]) @ Q.T
    x_rect = h[:, :3] / h[:, 3:]
    back = x_rect @ (rot1 @ R1.T).T + c1          # left camera -> C: rot1; rectified -> left camera: R1^T
    assert np.all(np.abs(back[:, 2] - X[:, 2]) <= 1e-3 * X[:, 2])
    assert np.all(np.linalg.norm(back - X, axis=1) <= 1e-3 * X[:, 2])


def test_cli_writes_the_files_and_rejects_bad_input(tmp_path, capsys):
    out = tmp_path / "cal"
    assert main(["export-calibration", "misaligned", "-o", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["left.yaml", "right.yaml", "stereo.yml"]
    printed = capsys.readouterr().out
    assert "left: model error over the image" in printed
    # the left view's stated error is the one pinhole_views computes
    doc_text = (out / "left.yaml").read_text()
    du = pinhole_views(load_rig("misaligned"))["left"].error_px[0]
    assert f"columns {du:.3g} px" in doc_text
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    afile = tmp_path / "afile"
    afile.write_text("keep")
    for args, msg in ((["nosuch", "-o", str(out)], "rig file not found"),
                      (["misaligned", "-o", str(out), "--near-mm", "900", "--far-mm", "500"],
                       "must be less than --far-mm"),
                      (["misaligned", "-o", str(afile)], "is a file")):
        assert main(["export-calibration", *args]) == 2
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before       # nothing half-written
    assert afile.read_text() == "keep"


def test_the_three_files_land_together_or_not_at_all(tmp_path, capsys):
    """A folder in the way of stereo.yml (an adversarial trial): exit 2 in one line, and the earlier left.yaml is
    what it was, no right.yaml written, no temporary file left; cleared, the three are written."""
    out = tmp_path / "out"
    (out / "stereo.yml").mkdir(parents=True)
    (out / "left.yaml").write_text("OLD CALIBRATION\n")
    assert main(["export-calibration", "misaligned", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "stereo.yml: it is a folder" in err
    assert (out / "left.yaml").read_text() == "OLD CALIBRATION\n"
    assert sorted(p.name for p in out.iterdir()) == ["left.yaml", "stereo.yml"]
    (out / "stereo.yml").rmdir()
    assert main(["export-calibration", "misaligned", "-o", str(out)]) == 0
    assert YAML(typ="safe").load((out / "left.yaml").read_text())["image_width"] == 640
    assert cv2.FileStorage(str(out / "stereo.yml"), cv2.FILE_STORAGE_READ).getNode("K1").mat().shape == (3, 3)


def test_a_range_inside_the_rig_is_refused_before_any_file(tmp_path, capsys):
    """--near-mm 10 lies inside the misaligned build's mirrors (44 mm): refused as every command refuses it (an
    adversarial trial: export-calibration took it), nothing written."""
    out = tmp_path / "ros"
    assert main(["export-calibration", "misaligned", "--near-mm", "10", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--near-mm 10 mm lies inside the rig" in err and not out.exists()
