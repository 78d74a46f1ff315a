"""Calibration export for ROS and OpenCV: each view of a rig as a rectified stereo camera
(:mod:`psvs.optics.pinhole_views`), written as

- ``left.yaml``, ``right.yaml``: ROS ``sensor_msgs/CameraInfo`` in camera_calibration_parsers' YAML (what
  ``camera_info_url`` loads): K, D (plumb_bob), R, P; P's Tx in metres (REP 103), Tx = -f' b for the right;
- ``stereo.yml``: an OpenCV FileStorage (``cv2.FileStorage``) with K1, D1, R1, P1, K2, D2, R2, P2, the
  right view's pose relative to the left (R, T: X_2 = R X_1 + T), Q (disparity -> 3-D in the left
  rectified frame, as ``cv2.reprojectImageTo3D`` takes it), each view's pose in psvs's frame C, in mm.

Both views are the *same* complex image: a stereo node gets it twice, as its left and its right image, and
each view's rectification brings that view's content onto the rows (the other view's content comes along,
unrectified: matching must tell them apart, psvs.match). The files' comments state the left view's model
error (the M1 plate makes it non-central) and the working range the rectification was fitted over.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from psvs.io.atomic import output_batch, write_atomic
from psvs.optics.pinhole_views import PinholeView

ROS_NAMES = {"left": "left.yaml", "right": "right.yaml"}
OPENCV_NAME = "stereo.yml"


def _matrix(name: str, m: np.ndarray) -> str:
    m = np.atleast_2d(np.asarray(m, float))
    data = ", ".join(repr(float(x)) for x in m.ravel())
    return f"{name}:\n  rows: {m.shape[0]}\n  cols: {m.shape[1]}\n  data: [{data}]\n"


def _limits(view: PinholeView, near_mm: float, far_mm: float) -> str:
    du, dv = view.error_px
    return (f"# model error over the image against psvs's exact optics: columns {du:.3g} px, rows {dv:.3g} px"
            + (" (the M1 plate: this view is not central; psvs itself triangulates with the exact model)"
               if view.name == "left" else "") + "\n"
            f"# rectification fitted over {near_mm:g}-{far_mm:g} mm; rectified grid "
            f"{view.rectified_size_px[0]}x{view.rectified_size_px[1]} px (ROS crops it to the image size)\n")


def camera_info_yaml(view: PinholeView, near_mm: float, far_mm: float, rig_name: str = "psvs") -> str:
    """One view as ROS CameraInfo YAML (camera_calibration_parsers' format); P's Tx in metres."""
    P = view.P.copy()
    P[:, 3] /= 1000.0                       # mm -> m (REP 103)
    w, h = view.image_size_px
    return ("# psvs export-calibration: the " + view.name + " view of " + rig_name + " (sensor_msgs/CameraInfo)\n"
            "# both views are the same complex image: feed it as the left and as the right image\n"
            + _limits(view, near_mm, far_mm) +
            f"image_width: {w}\nimage_height: {h}\ncamera_name: psvs_{view.name}\n"
            + _matrix("camera_matrix", view.K)
            + "distortion_model: plumb_bob\n"
            + _matrix("distortion_coefficients", view.D.reshape(1, -1))
            + _matrix("rectification_matrix", view.R)
            + _matrix("projection_matrix", P))


def stereo_filestorage(views: dict[str, PinholeView], near_mm: float, far_mm: float) -> str:
    """Both views as an OpenCV FileStorage YAML document (mm): see the module docstring for the keys."""
    left, right = views["left"], views["right"]
    R = right.rotation.T @ left.rotation
    T = right.rotation.T @ (left.centre_mm - right.centre_mm)
    kp = left.P[:, :3]
    baseline = -right.P[0, 3] / right.P[0, 0]
    Q = np.array([[1.0, 0.0, 0.0, -kp[0, 2]], [0.0, 1.0, 0.0, -kp[1, 2]], [0.0, 0.0, 0.0, kp[0, 0]],
                  [0.0, 0.0, 1.0 / baseline, 0.0]])
    fs = cv2.FileStorage("stereo.yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.writeComment("psvs export-calibration: both views of one complex image as a rectified stereo pair (mm)")
    for view in (left, right):
        for line in _limits(view, near_mm, far_mm).splitlines():
            fs.writeComment(f"{view.name}: {line[2:]}")
    fs.write("image_width", int(left.image_size_px[0]))
    fs.write("image_height", int(left.image_size_px[1]))
    fs.write("rectified_width", int(left.rectified_size_px[0]))
    fs.write("rectified_height", int(left.rectified_size_px[1]))
    fs.write("near_mm", float(near_mm))
    fs.write("far_mm", float(far_mm))
    for k, view in ((1, left), (2, right)):
        fs.write(f"K{k}", view.K)
        fs.write(f"D{k}", view.D.reshape(1, -1))
        fs.write(f"R{k}", view.R)
        fs.write(f"P{k}", view.P)
        fs.writeComment(f"the {view.name} view camera's axes (columns) and centre in psvs's frame C, mm")
        fs.write(f"rotation_in_rig{k}", view.rotation)
        fs.write(f"centre_in_rig{k}", view.centre_mm.reshape(3, 1))
    fs.write("R", R)
    fs.write("T", T.reshape(3, 1))
    fs.write("Q", Q)
    fs.write("error_left_px", np.array(left.error_px).reshape(1, 2))
    fs.write("error_right_px", np.array(right.error_px).reshape(1, 2))
    return fs.releaseAndGetString()


def write_calibration_files(folder, views: dict[str, PinholeView], near_mm: float, far_mm: float,
                            rig_name: str = "psvs") -> list[Path]:
    """Write left.yaml, right.yaml (ROS) and stereo.yml (OpenCV) into ``folder`` (created; the three as one batch:
    all or none, :func:`psvs.io.atomic.output_batch`). Returns the paths written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    texts = {ROS_NAMES[v]: camera_info_yaml(views[v], near_mm, far_mm, rig_name) for v in ("left", "right")}
    texts[OPENCV_NAME] = stereo_filestorage(views, near_mm, far_mm)
    paths = []
    with output_batch():            # all three land, or none (a folder in the way of the last kept the first two)
        for name, text in texts.items():
            write_atomic(folder / name, text)
            paths.append(folder / name)
    return paths
