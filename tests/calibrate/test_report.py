"""The calibration report's figures have the image's shape: read back with OpenCV, the plotted area of each
PNG (inside the axes' frame) is as wide against as tall as the camera's image, for a 1440 x 1080 and a
640 x 480 camera, also where matplotlib's settings would stretch an image to fill its axes."""
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
    assert [p.name for p in written] == ["residuals.png", "vertical_disagreement.png"]
    for path in written:
        width, height = plot_frame_px(path)
        assert width / height == pytest.approx(w / h, rel=0.02), (path.name, width, height)
        assert width > 400                                   # the map is not shrunk to fit
