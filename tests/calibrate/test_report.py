"""The calibration report, read back by independent readers: residuals.csv (Python's csv) holds every
detection and residual exactly; the figures (OpenCV) have the image's shape: the plotted area of each PNG
(inside the axes' frame) is as wide against as tall as the camera's image, for a 1440 x 1080 and a 640 x 480
camera, also where matplotlib's settings would stretch an image to fill its axes."""
import csv

import matplotlib
import numpy as np
import pytest

from psvs.calibrate.bundle import BundleResult
from psvs.calibrate.report import write_report
from psvs.optics.rig import Camera, Mirrors, Rig

CAMERAS = {"1440x1080": Camera(focal_length_mm=8.0, pixel_pitch_mm=(0.00345, 0.00345), image_size_px=(1440, 1080)),
           "640x480": Camera(focal_length_mm=11.3, pixel_pitch_mm=(0.01, 0.01), image_size_px=(640, 480))}


def bundle_result(rig: Rig) -> BundleResult:
    """A calibration's result with two detections per view (enough for the residual plot)."""
    w, h = rig.camera.image_size_px
    pts = np.array([[0.2 * w, 0.3 * h], [0.7 * w, 0.6 * h]])
    res = np.array([[0.01, -0.02], [0.0, 0.03]])
    return BundleResult(rig=rig, values={}, sigma={}, held_by_prior=(), rms_px=0.02,
                        rms_by_view={"left": 0.02, "right": 0.02}, rms_by_image={"a": 0.02},
                        residuals={"a": (res, res)}, observed={"a": (pts, pts)}, poses={}, success=True, message="")


def _longest_runs(mask: np.ndarray) -> np.ndarray:
    """Per row of a boolean image, the length of its longest run of True."""
    out = np.zeros(len(mask), int)
    for k, row in enumerate(mask):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], row.astype(int), [0]])))
        out[k] = (edges[1::2] - edges[::2]).max() if len(edges) else 0
    return out


def plot_frame_px(path) -> tuple[int, int]:
    """(width, height) in PNG pixels of the main axes' frame: its top and bottom edges are the first and
    last dark lines running across over 30 % of the figure, its left and right edges the first two dark
    lines running down over 30 % of it (a colour bar lies further right)."""
    import cv2
    img = cv2.imread(str(path))
    assert img is not None, path
    dark = img.max(axis=2) < 80
    rows = np.flatnonzero(_longest_runs(dark) > 0.3 * dark.shape[1])
    cols = np.flatnonzero(_longest_runs(dark.T) > 0.3 * dark.shape[0])
    cols = cols[np.concatenate([[True], np.diff(cols) > 1])]          # one column per line
    return int(cols[1] - cols[0]), int(rows[-1] - rows[0])


@pytest.mark.parametrize("stretch", [False, True], ids=["default", "image.aspect=auto"])
@pytest.mark.parametrize("camera", list(CAMERAS))
def test_figures_have_the_image_shape(tmp_path, camera, stretch):
    rig = Rig(CAMERAS[camera], Mirrors())
    w, h = rig.camera.image_size_px
    with matplotlib.rc_context({"image.aspect": "auto"} if stretch else {}):
        written = write_report(tmp_path, bundle_result(rig))
    assert [p.name for p in written] == ["residuals.csv", "residuals.png", "vertical_disagreement.png"]
    for path in written[1:]:
        width, height = plot_frame_px(path)
        assert width / height == pytest.approx(w / h, rel=0.02), (path.name, width, height)
        assert width > 400                                   # the map is not shrunk to fit


def test_residuals_csv_reads_back_exactly(tmp_path):
    res = bundle_result(Rig(CAMERAS["640x480"], Mirrors()))
    left_res = np.array([[0.0123456789012345, -1e-7], [2.5, -0.3]])
    res.residuals["b"] = (left_res, -left_res)
    res.observed["b"] = (np.array([[10.25, 20.5], [600.125, 470.0]]), np.array([[11.0, 21.0], [30.0, 40.0]]))
    write_report(tmp_path, res)
    with (tmp_path / "residuals.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["image", "view", "u_px", "v_px", "du_px", "dv_px"]
    assert len(rows) == 8
    for name in ("a", "b"):
        for k, view in enumerate(("left", "right")):
            got = [r for r in rows if r["image"] == name and r["view"] == view]
            uv = np.array([[float(r["u_px"]), float(r["v_px"])] for r in got])
            duv = np.array([[float(r["du_px"]), float(r["dv_px"])] for r in got])
            assert np.array_equal(uv, res.observed[name][k]) and np.array_equal(duv, res.residuals[name][k])
