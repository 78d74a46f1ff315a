"""OpenCV-style circle grids and chessboards in complex images, and a generic stereo calibration (OpenCV).

Without a rig: :func:`detect_grid` needs the card's two copies apart. With the rig, a card whose copies
interleave or touch, an asymmetric grid or a ChArUco board: :func:`psvs.targets.detect.detect_target`
(what ``psvs calibrate`` uses).

Each disc appears twice. All dark blobs are found and refined as for the paper's pattern
(:mod:`psvs.targets.pattern`), split into the two views by a two-cluster split along u (the grid must
be narrower than its disparity, so the copies do not interleave: the left view is the right-hand copy),
and each copy ordered on its own with ``cv2.findCirclesGrid`` run on a clean synthetic image of its
centres; the right copy's order is then turned to agree with the left's (twins all sit one shift apart),
so a build whose views disagree by many rows pairs them right. The generic calibration treats the two
views as two pinhole cameras with *shared* intrinsics (one lens): ``cv2.calibrateCamera`` on every view
for K and the distortion, then ``cv2.stereoCalibrate`` with them fixed for R and T. (The M1 plate makes
the left view slightly non-central; this model absorbs that into R, T and the residual.)
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.targets.discs import MAX_DIAMETER_PX, dark_blobs
from psvs.targets.rim import refine_circle

#: A disc whose surroundings vary more than this (share of its contrast) is not trusted for calibration.
MAX_BACKGROUND_SPREAD = 0.25


@dataclass(frozen=True, eq=False)
class GridDetection:
    """left, right: (rows * cols, 2) px, the same disc in the same row of both. ``reliable``
    (rows * cols,) bool: both copies of the disc lie on an even ground (no other view's card edge across
    them), so their centres are unbiased; None when not assessed (every point trusted)."""

    left: np.ndarray
    right: np.ndarray
    reliable: np.ndarray | None = None


def _pair_views(left: np.ndarray, right: np.ndarray, what: str) -> GridDetection:
    """Pair each (ordered) left-view point with the right-view point nearest to it shifted back by the
    median disparity; ValueError("could not pair the <what>") unless the pairing is one to one."""
    shift = np.median(left[:, 0]) - np.median(right[:, 0])
    twin = [int(np.argmin(np.linalg.norm(right - (p - [shift, 0.0]), axis=1))) for p in left]
    if len(set(twin)) != len(left):
        raise ValueError(f"could not pair the {what}")
    return GridDetection(left, right[twin])


def _order(points: np.ndarray, radius: float, rows: int, cols: int, shape) -> np.ndarray | None:
    """The points (rows * cols, 2) in ``cv2.findCirclesGrid``'s grid order, or None when they form no grid."""
    canvas = np.full(shape, 255, np.uint8)
    for u, v in points:
        cv2.circle(canvas, (int(round(u * 4)), int(round(v * 4))), int(round(radius * 4)), 0, -1, cv2.LINE_AA, 2)
    ok, found = cv2.findCirclesGrid(canvas, (cols, rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
    if not ok:
        return None
    found = found.reshape(-1, 2)  # (N, 1, 2) in OpenCV 4, (N, 2) in OpenCV 5
    idx = [int(np.argmin(np.linalg.norm(points - f, axis=1))) for f in found]
    return points[idx] if len(set(idx)) == len(idx) else None


def _pair_orders(left: np.ndarray, right: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """The right view's grid order turned (a half turn; a quarter turn too for a square grid) to label
    each disc as the left view does: twins sit one shift apart (the disparity, and the rows a build puts
    between the views), so the right order whose left-minus-right offsets agree best is the one.

    ``cv2.findCirclesGrid`` may start a grid at any corner; only turns are tried, never a mirror image:
    both views see the card through two mirrors each, so neither is mirrored.
    """
    g = right.reshape(rows, cols, 2)
    turns = [g, g[::-1, ::-1]]
    if rows == cols:
        turns += [np.rot90(g, 1), np.rot90(g, 3)]
    spread = [np.linalg.norm(np.std(left - t.reshape(-1, 2), axis=0)) for t in turns]
    return turns[int(np.argmin(spread))].reshape(-1, 2)


def detect_grid(grey: np.ndarray, rows: int, cols: int, max_diameter_px: int = MAX_DIAMETER_PX) -> GridDetection:
    """Both views of a ``rows`` x ``cols`` circle grid; ValueError naming the problem when it is not there."""
    n = rows * cols
    blobs = dark_blobs(grey, max_diameter_px)
    if len(blobs) < 2 * n:
        raise ValueError(f"found {len(blobs)} disc(s), expected {2 * n} ({rows}x{cols} per view)")
    ells = [refine_circle(grey, c, r) for c, r in blobs]
    pts = np.array([e.centre_px for e in ells])
    spread = np.array([e.background_spread for e in ells])
    radius = float(np.median([np.mean(e.axes_px) for e in ells]))
    # the two copies side by side: split at the widest gap along u that leaves each side a whole grid
    # (a stray dark blob -- the gap where two cards nearly touch -- may add a point to either side)
    us = np.sort(pts[:, 0])
    order = np.argsort(pts[:, 0])
    cuts = range(n, len(pts) - n + 1)
    k = max(cuts, key=lambda c: us[c] - us[c - 1])
    if us[k] - us[k - 1] <= 0.5 * radius:
        raise ValueError("the grid's two views interleave: use a grid narrower than its disparity")
    right, left = pts[order[:k]], pts[order[k:]]
    ordered = [_order(view, radius, rows, cols, grey.shape) for view in (left, right)]
    if ordered[0] is None or ordered[1] is None:
        which = "left" if ordered[0] is None else "right"
        raise ValueError(f"the {which} view's discs do not form a {rows}x{cols} grid")
    ordered[1] = _pair_orders(ordered[0], ordered[1], rows, cols)
    # each ordered point is one of the refined centres: look up its ground's spread
    even = [spread[np.argmin(np.linalg.norm(pts[:, None, :] - o[None, :, :], axis=2), axis=0)]
            <= MAX_BACKGROUND_SPREAD for o in ordered]
    return GridDetection(ordered[0], ordered[1], even[0] & even[1])


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
