"""A ChArUco board in both views of a complex image (OpenCV's aruco module).

Every ArUco marker of the board appears twice, once per view, with the same id: OpenCV's
``ArucoDetector`` finds them all, and each id's two copies are the two views' (the left view's copy is the
one further along +u: disparity u_l - u_r > 0), provided the right copy lies on the left copy's epipolar
curve through the nominal rig (:func:`psvs.targets.twins.twin_candidates`). A marker seen once (its twin
hidden or unreadable) joins the view whose board map (a homography fitted to the paired markers) predicts
it. Each view's markers then go to OpenCV's ``CharucoDetector``, which finds the chessboard corners between
them (ids: OpenCV's, row by row) and refines them; a corner of one view is paired with the same id's corner of
the other. A corner inside the other view's printed board (its squares and markers run across the corner's
refinement window) is not trusted.
"""
from __future__ import annotations

import cv2
import numpy as np

from psvs.optics.rig import Rig
from psvs.simulate.textures import CharucoBoard
from psvs.targets.target_points import TargetDetection
from psvs.targets.twins import twin_candidates

#: A lone marker joins a view whose board map puts it within this share of a square.
LONE_TOL = 0.25


def opencv_board(board: CharucoBoard):
    """OpenCV's ``cv2.aruco.CharucoBoard`` of a board (OpenCV's board frame: origin at the top-left corner)."""
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, board.dictionary))
    return cv2.aruco.CharucoBoard((board.squares_x, board.squares_y), board.square_mm, board.marker_mm, d)


def _markers(grey: np.ndarray, cv_board) -> tuple[list[np.ndarray], np.ndarray]:
    """All ArUco markers of the board's dictionary in the image: corners (k, 4, 2) px and ids (k,)."""
    detector = cv2.aruco.ArucoDetector(cv_board.getDictionary(), cv2.aruco.DetectorParameters())
    corners, ids, _ = detector.detectMarkers(grey)
    if ids is None or len(ids) == 0:
        return [], np.zeros(0, int)
    valid = set(np.asarray(cv_board.getIds()).ravel().tolist())
    keep = [k for k, i in enumerate(np.asarray(ids).ravel()) if int(i) in valid]
    return [np.asarray(corners[k], float).reshape(4, 2) for k in keep], np.asarray(ids).ravel()[keep].astype(int)


def split_markers(corners: list[np.ndarray], ids: np.ndarray, board: CharucoBoard, rig: Rig) -> tuple[dict, dict]:
    """The markers of each view: ({id: corners (4, 2)} left, {id: corners} right)."""
    left, right, lone = {}, {}, []
    centres = np.array([c.mean(axis=0) for c in corners]).reshape(-1, 2)
    for i in np.unique(ids):
        k = np.flatnonzero(ids == i)
        if len(k) == 2:
            a, b = (k[0], k[1]) if centres[k[0], 0] > centres[k[1], 0] else (k[1], k[0])
            if 1 in twin_candidates(centres[[a, b]], rig)[0]:
                left[int(i)], right[int(i)] = corners[a], corners[b]
        elif len(k) == 1:
            lone.append(int(k[0]))
    cv_board = opencv_board(board)
    obj = np.asarray(cv_board.getObjPoints(), float)[:, :, :2]          # (markers, 4, 2) mm, OpenCV's frame
    step = board.square_mm
    for view in (left, right):
        if len(view) < 2 or not lone:
            continue
        src = np.concatenate([obj[i] for i in view])
        dst = np.concatenate(list(view.values()))
        H, _ = cv2.findHomography(src, dst, 0)
        if H is None:
            continue
        scale = np.sqrt(abs(np.linalg.det(H[:2, :2]))) / abs(H[2, 2])   # px per mm, roughly
        for k in lone:
            i = int(ids[k])
            guess = cv2.perspectiveTransform(obj[i].reshape(-1, 1, 2), H).reshape(4, 2)
            if i not in view and np.abs(guess - corners[k]).max() < LONE_TOL * step * scale:
                view[i] = corners[k]
    return left, right


def _corners(grey: np.ndarray, markers: dict, cv_board) -> dict:
    """{charuco id: corner (2,) px} of one view's markers (OpenCV's CharucoDetector)."""
    if len(markers) < 2:
        return {}
    det = cv2.aruco.CharucoDetector(cv_board)
    ids = np.array(list(markers.keys()), np.int32).reshape(-1, 1)
    mc = tuple(np.asarray(c, np.float32).reshape(1, 4, 2) for c in markers.values())
    ch_corners, ch_ids, _, _ = det.detectBoard(grey, markerCorners=mc, markerIds=ids)
    if ch_ids is None or len(ch_ids) == 0:
        return {}
    pts = np.asarray(ch_corners, float).reshape(-1, 2)
    return {int(i): p for i, p in zip(np.asarray(ch_ids).ravel(), pts, strict=True)}


def detect_charuco(grey: np.ndarray, board: CharucoBoard, rig: Rig):
    """Both views of a ChArUco board (see the module docstring): a
    :class:`psvs.targets.detect.TargetDetection`, or ValueError saying why not."""
    cv_board = opencv_board(board)
    corners, ids = _markers(grey, cv_board)
    if len(ids) == 0:
        raise ValueError(f"found no ArUco marker of {board.dictionary}: hold the whole board in view, closer if "
                         "its markers are small")
    left, right = split_markers(corners, ids, board, rig)
    if len(left) < 2:
        raise ValueError(f"found {len(ids)} ArUco marker(s) but {len(left)} seen in both views: hold the whole "
                         "board in both views (nearer the middle of the image)")
    cl, cr = _corners(grey, left, cv_board), _corners(grey, right, cv_board)
    common = sorted(set(cl) & set(cr))
    if len(common) < 4:
        raise ValueError(f"{len(common)} chessboard corner(s) of the ChArUco board found in both views: hold the "
                         "board closer, or less tilted")
    L = np.array([cl[i] for i in common])
    R = np.array([cr[i] for i in common])
    reliable = ~_inside_board(L, right, board, cv_board) & ~_inside_board(R, left, board, cv_board)
    n = (board.squares_x - 1) * (board.squares_y - 1)
    return TargetDetection(np.array(common), L, R, reliable, len(common) == n)


def _inside_board(points: np.ndarray, markers: dict, board: CharucoBoard, cv_board) -> np.ndarray:
    """Points (n, 2) px inside the board that ``markers`` (another view's) show, grown by half a square."""
    obj = np.asarray(cv_board.getObjPoints(), float)[:, :, :2]
    src = np.concatenate([obj[i] for i in markers])
    H, _ = cv2.findHomography(src, np.concatenate(list(markers.values())), 0)
    if H is None:
        return np.zeros(len(points), bool)
    s = board.square_mm
    w, h = board.squares_x * s, board.squares_y * s
    outline = np.array([[-s / 2, -s / 2], [w + s / 2, -s / 2], [w + s / 2, h + s / 2], [-s / 2, h + s / 2]])
    poly = cv2.perspectiveTransform(outline.reshape(-1, 1, 2), H).reshape(-1, 2).astype(np.float32)
    return np.array([cv2.pointPolygonTest(poly, (float(u), float(v)), False) >= 0 for u, v in points])
