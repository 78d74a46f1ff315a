"""Each view of a rig as a standard (OpenCV / ROS) rectified stereo camera: K, D, R, P, and how well that
model holds.

A view is the real camera (K, D: its focal length in px, principal point and OpenCV lens model) seen
through the view's mirrors: a *virtual camera* whose axes are the real camera's turned by the mirrors'
reflections (:func:`psvs.optics.mirrors.direction_map`, two reflections: a proper rotation) and whose
centre is the dual rectification's (:mod:`psvs.optics.rectify`). R turns the virtual camera's frame into
the rectified frame shared by both views, and P = K' [I | t] projects into the rectified image, with the
right view one baseline along x' (OpenCV's ``stereoRectify`` conventions: P2[0, 3] = -f' b).

The right view (two reflections) is such a camera exactly. The left view is not quite: the tilted M1
plate displaces each ray sideways by an amount that depends on its direction, so no single centre fits
every ray. Its K, D, R, P are a pinhole through the rectification's left centre; :attr:`PinholeView.error_px`
states how far it is from the exact rectified coordinates over the image (examples/rigs/misaligned.toml,
3 mm plate: columns 0.48 px, rows 0.09 px), and stereo tools that use these files (cv2.remap of
``initUndistortRectifyMap``, ROS image_proc) get the left view to that accuracy; psvs's own matching and
triangulation use the exact model instead.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.optics.mirrors import direction_map
from psvs.optics.rectify import VIEWS, rectify
from psvs.optics.rig import Rig


@dataclass(frozen=True)
class PinholeView:
    """One view as a rectified stereo camera (OpenCV's and ROS's conventions; lengths mm, pixels px).

    K : (3, 3) the real camera's matrix, px.      D : (5,) k1, k2, p1, p2, k3 (OpenCV's order).
    R : (3, 3) view camera frame -> rectified frame.
    P : (3, 4) rectified projection [K' | K' t], t = (0, 0, 0) left, (-b', 0, 0) right; P[0, 3] mm * px/mm.
    rotation : (3, 3) columns are the view camera's axes in frame C.  centre_mm : (3,) its centre in C.
    image_size_px : (width, height) of the complex image.  rectified_size_px : of the rectified grid.
    error_px : (columns, rows) largest |u'|, |v'| difference between K, D, R, P and the exact rectified
        coordinates over the image, px (the right view: ~1e-10; the left: the plate, see the module).
    """

    name: str
    K: np.ndarray
    D: np.ndarray
    R: np.ndarray
    P: np.ndarray
    rotation: np.ndarray
    centre_mm: np.ndarray
    image_size_px: tuple[int, int]
    rectified_size_px: tuple[int, int]
    error_px: tuple[float, float]


def camera_matrix(rig: Rig) -> np.ndarray:
    """The real camera's K (3, 3), px: fx = f / pitch_x, fy = f / pitch_y, principal point (cx, cy)."""
    cam = rig.camera
    cx, cy = cam.principal_point_px
    return np.array([[cam.focal_length_mm / cam.pixel_pitch_mm[0], 0.0, cx],
                     [0.0, cam.focal_length_mm / cam.pixel_pitch_mm[1], cy],
                     [0.0, 0.0, 1.0]])


def pinhole_views(rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> dict[str, PinholeView]:
    """Both views of ``rig`` as rectified stereo cameras over the working range near..far (mm):
    {'left': PinholeView, 'right': PinholeView}. See the module docstring for what holds exactly."""
    rect = rectify(rig, float(near_mm), float(far_mm))
    K, D = camera_matrix(rig), np.array(rig.camera.distortion, float)
    Kp = rect.camera_matrix
    out = {}
    for view in VIEWS:
        rot = direction_map(rig, view)
        R = rect.rotation @ rot
        t = np.zeros(3) if view == "left" else np.array([-rect.baseline_mm, 0.0, 0.0])
        P = np.hstack([Kp, (Kp @ t)[:, None]])
        out[view] = PinholeView(view, K, D, R, P, rot, rect.centres_mm[view].copy(), rig.camera.image_size_px,
                                rect.size_px, _model_error(rect, K, D, R, P, view))
    return out


def rectified_by_model(uv_px: np.ndarray, view: PinholeView) -> np.ndarray:
    """Rectified pixels (N, 2) of complex-image pixels (N, 2) through K, D, R, P (cv2.undistortPoints), the
    way a standard stereo tool reads the files."""
    return undistort_points(uv_px, view.K, view.D, view.R, view.P)


def undistort_points(uv_px: np.ndarray, K: np.ndarray, D: np.ndarray, R: np.ndarray | None = None,
                     P: np.ndarray | None = None) -> np.ndarray:
    """OpenCV's ``undistortPoints`` (N, 2) -> (N, 2), iterated to convergence (50 steps, 1e-10) rather than
    its default 5 steps, which leave ~0.1 px at k1 = -0.2 in the corners. OpenCV 4 names that overload
    ``undistortPointsIter``; OpenCV 5 folds it into ``undistortPoints(..., criteria=)``."""
    uv = np.asarray(uv_px, float).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    R = np.eye(3) if R is None else R
    P = K if P is None else P
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(uv, K, D, R, P, crit).reshape(-1, 2)
    return cv2.undistortPoints(uv, K, D, R=R, P=P, criteria=crit).reshape(-1, 2)


def _model_error(rect, K, D, R, P, view: str) -> tuple[float, float]:
    w, h = rect.rig.camera.image_size_px
    uu, vv = np.meshgrid(np.linspace(0, w - 1, 33), np.linspace(0, h - 1, 25))
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    exact = rect.to_rectified(uv, view)
    tmp = PinholeView(view, K, D, R, P, np.eye(3), np.zeros(3), (w, h), rect.size_px, (0.0, 0.0))
    diff = np.abs(rectified_by_model(uv, tmp) - exact)
    diff = diff[np.all(np.isfinite(diff), axis=1)]
    return (float(diff[:, 0].max()), float(diff[:, 1].max())) if len(diff) else (float("nan"),) * 2
