"""OpenCV-style circle grids and chessboards in complex images, and a generic stereo calibration (OpenCV).

Each disc appears twice. All dark blobs are found and refined as for the paper's pattern
(:mod:`psvs.calibrate.targets`), split into the two views by a two-cluster split along u (the grid must
be narrower than its disparity, so the copies do not interleave: the left view is the right-hand copy),
ordered with ``cv2.findCirclesGrid`` run on a clean synthetic image of the left copy's centres, and the
right copy's discs paired with them through the median disparity. The generic calibration treats the two
views as two pinhole cameras with *shared* intrinsics (one lens): ``cv2.calibrateCamera`` on every view
for K and the distortion, then ``cv2.stereoCalibrate`` with them fixed for R and T. (The M1 plate makes
the left view slightly non-central; this model absorbs that into R, T and the residual.)
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.calibrate.targets import dark_blobs, refine_circle


@dataclass(frozen=True, eq=False)
class GridDetection:
    """left, right: (rows * cols, 2) px, the same disc in the same row of both."""

    left: np.ndarray
    right: np.ndarray


def _pair_views(left: np.ndarray, right: np.ndarray, what: str) -> GridDetection:
    """Pair each (ordered) left-view point with the right-view point nearest to it shifted back by the
    median disparity; ValueError("could not pair the <what>") unless the pairing is one to one."""
    shift = np.median(left[:, 0]) - np.median(right[:, 0])
    twin = [int(np.argmin(np.linalg.norm(right - (p - [shift, 0.0]), axis=1))) for p in left]
    if len(set(twin)) != len(left):
        raise ValueError(f"could not pair the {what}")
    return GridDetection(left, right[twin])


def _order(points: np.ndarray, radius: float, rows: int, cols: int, shape) -> np.ndarray | None:
    canvas = np.full(shape, 255, np.uint8)
    for u, v in points:
        cv2.circle(canvas, (int(round(u * 4)), int(round(v * 4))), int(round(radius * 4)), 0, -1, cv2.LINE_AA, 2)
    ok, found = cv2.findCirclesGrid(canvas, (cols, rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
    if not ok:
        return None
    found = found.reshape(-1, 2)  # (N, 1, 2) in OpenCV 4, (N, 2) in OpenCV 5
    idx = [int(np.argmin(np.linalg.norm(points - f, axis=1))) for f in found]
    return points[idx] if len(set(idx)) == len(idx) else None


def detect_grid(grey: np.ndarray, rows: int, cols: int, max_diameter_px: int = 40) -> GridDetection:
    """Both views of a ``rows`` x ``cols`` circle grid; ValueError naming the problem when it is not there."""
    n = rows * cols
    blobs = dark_blobs(grey, max_diameter_px)
    if len(blobs) != 2 * n:
        raise ValueError(f"found {len(blobs)} disc(s), expected {2 * n} ({rows}x{cols} per view)")
    ells = [refine_circle(grey, c, r) for c, r in blobs]
    pts = np.array([e.centre_px for e in ells])
    radius = float(np.mean([np.mean(e.axes_px) for e in ells]))
    order = np.argsort(pts[:, 0])
    right, left = pts[order[:n]], pts[order[n:]]
    if right[:, 0].max() >= left[:, 0].min():
        raise ValueError("the grid's two views interleave: use a grid narrower than its disparity")
    ordered = _order(left, radius, rows, cols, grey.shape)
    if ordered is None:
        raise ValueError(f"the discs do not form a {rows}x{cols} grid")
    return _pair_views(ordered, right, "grid's two views disc by disc")


@dataclass(frozen=True, eq=False)
class StereoCalibration:
    """K (3, 3) px, dist (5,) OpenCV's (k1, k2, p1, p2, k3), R (3, 3) and T (3,) mm mapping left-camera
    points to right-camera points, and the reprojection RMS (px) of both steps."""

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    T: np.ndarray
    rms_intrinsics_px: float
    rms_stereo_px: float


def calibrate_stereo(detections: list[GridDetection], rows: int, cols: int, spacing_mm: float,
                     image_size_px: tuple[int, int]) -> StereoCalibration:
    """Generic stereo calibration (shared intrinsics) from target detections (circle grids, or chessboard
    inner corners with ``spacing_mm`` the square size) in several poses."""
    if len(detections) < 3:
        raise ValueError(f"stereo calibration needs at least 3 grid poses, got {len(detections)}")
    j, i = np.meshgrid(np.arange(cols), np.arange(rows))
    obj = np.column_stack([j.ravel() * spacing_mm, i.ravel() * spacing_mm, np.zeros(rows * cols)]).astype(np.float32)
    img_l = [d.left.astype(np.float32).reshape(-1, 1, 2) for d in detections]
    img_r = [d.right.astype(np.float32).reshape(-1, 1, 2) for d in detections]
    flags = cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3   # k1 only: a few poses cannot pin k2
    rms_i, K, dist, _, _ = cv2.calibrateCamera([obj] * (2 * len(detections)), img_l + img_r, image_size_px,
                                               None, None, flags=flags)
    rms_s, _, _, _, _, R, T, _, _ = cv2.stereoCalibrate([obj] * len(detections), img_l, img_r, K, dist, K, dist,
                                                        image_size_px, flags=cv2.CALIB_FIX_INTRINSIC)
    return StereoCalibration(K, dist.ravel(), R, T.ravel(), float(rms_i), float(rms_s))


def detect_chessboard(grey: np.ndarray, rows: int, cols: int) -> GridDetection:
    """Both views of a chessboard with ``rows`` x ``cols`` inner corners.

    OpenCV finds one board; its region is painted over with the image's median grey and the search is
    repeated for the second. Corners are refined with ``cv2.cornerSubPix``; the right-hand copy is the left
    view; its corners are paired with the other copy's through the median disparity.
    """
    img = np.ascontiguousarray(grey)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    boards = []
    work = img.copy()
    for _ in range(2):
        ok, corners = cv2.findChessboardCorners(work, (cols, rows), flags=flags)
        if not ok:
            raise ValueError(f"found {len(boards)} of the 2 views of a {rows}x{cols} chessboard")
        corners = cv2.cornerSubPix(img, corners, (5, 5), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3))
        pts = corners.reshape(-1, 2).astype(np.float64)  # OpenCV 4: (N, 1, 2); 5: (N, 2)
        boards.append(pts)
        hull = cv2.convexHull(pts.astype(np.float32))
        centre = pts.mean(axis=0)
        grown = (centre + 1.6 * (hull.reshape(-1, 2) - centre)).astype(np.int32)   # the border squares too
        cv2.fillConvexPoly(work, grown, int(np.median(img)))
    a, b = boards
    left, right = (a, b) if a[:, 0].mean() > b[:, 0].mean() else (b, a)
    return _pair_views(left, right, "chessboard's two views corner by corner")
