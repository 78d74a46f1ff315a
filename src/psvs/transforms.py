"""Rigid transforms as 4 x 4 homogeneous matrices, named ``A2B`` (maps points from frame A into frame B).

One place builds, inverts, chains and checks them, as pytransform3d does (``transform_from``,
``invert_transform``, ``concat``): rotations (3, 3), translations (3,) in mm.

Examples
--------
>>> import numpy as np
>>> R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])    # 90 deg about z
>>> A2B = transform_from(R, [10.0, 0.0, 0.0])
>>> transform_points(A2B, [[1.0, 0.0, 0.0]])
array([[10.,  1.,  0.]])
>>> np.allclose(concat(A2B, invert_transform(A2B)), np.eye(4))
True
"""
from __future__ import annotations

import numpy as np

#: Tolerance of :func:`check_transform` on R^T R = I and on the last row.
RIGID_TOL = 1e-6


def transform_from(R, p) -> np.ndarray:
    """The transform (4, 4) with rotation ``R`` (3, 3) and translation ``p`` (3,), mm."""
    A2B = np.eye(4)
    A2B[:3, :3] = np.asarray(R, dtype=np.float64)
    A2B[:3, 3] = np.asarray(p, dtype=np.float64)
    return A2B


def translation(p) -> np.ndarray:
    """A pure translation by ``p`` (3,) mm, (4, 4)."""
    return transform_from(np.eye(3), p)


def rotation(R) -> np.ndarray:
    """A pure rotation ``R`` (3, 3) about the origin, (4, 4)."""
    return transform_from(R, np.zeros(3))


def matrix_from_rotvec(rotvec) -> np.ndarray:
    """The rotation (3, 3) of rotation vector ``rotvec`` (3,) rad (axis times angle), by Rodrigues' formula
    R = I + sin(t) K + (1 - cos(t)) K^2 (K the cross-product matrix of the unit axis); its series near t = 0.
    (What scipy's Rotation.from_rotvec gives, without loading scipy.spatial on a command's start.)"""
    v = np.asarray(rotvec, dtype=np.float64)
    if v.shape != (3,):
        raise ValueError(f"rotvec must have shape (3,), got {v.shape}")
    t2 = float(v @ v)
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    if t2 < 1e-12:      # sin(t)/t and (1 - cos t)/t^2 by their series
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        t = np.sqrt(t2)
        a, b = np.sin(t) / t, (1.0 - np.cos(t)) / t2
    return np.eye(3) + a * K + b * (K @ K)


def transform_from_rotvec(rotvec, p) -> np.ndarray:
    """The transform (4, 4) with the rotation of rotation vector ``rotvec`` (3,) rad and translation ``p``
    (3,) mm."""
    return transform_from(matrix_from_rotvec(rotvec), p)


def invert_transform(A2B) -> np.ndarray:
    """B2A (4, 4) of a rigid A2B: (R^T, -R^T p), exact for a rigid transform (no general inverse)."""
    A2B = np.asarray(A2B, dtype=np.float64)
    R, p = A2B[:3, :3], A2B[:3, 3]
    return transform_from(R.T, -R.T @ p)


def concat(*transforms) -> np.ndarray:
    """Chain transforms in the order they apply: ``concat(A2B, B2C)`` is A2C (= B2C @ A2B)."""
    out = np.eye(4)
    for T in transforms:
        out = np.asarray(T, dtype=np.float64) @ out
    return out


def transform_points(A2B, points_mm) -> np.ndarray:
    """Points (N, 3) mm of frame A in frame B, (N, 3)."""
    A2B = np.asarray(A2B, dtype=np.float64)
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)
    return pts @ A2B[:3, :3].T + A2B[:3, 3]


def check_transform(A2B, name: str = "transform", tol: float = RIGID_TOL) -> np.ndarray:
    """``A2B`` as a float64 (4, 4) rigid transform, or ValueError naming ``name``: finite, last row
    (0, 0, 0, 1), rotation orthonormal (R^T R = I within ``tol``) with determinant +1."""
    try:
        T = np.asarray(A2B, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a 4 x 4 matrix of numbers") from None
    if T.shape != (4, 4):
        raise ValueError(f"{name} must be 4 x 4, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError(f"{name} must hold finite numbers")
    R = T[:3, :3]
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=tol) or not np.allclose(R.T @ R, np.eye(3), atol=tol) \
            or np.linalg.det(R) < 0:
        raise ValueError(f"{name} is not a rigid transform (its rotation is not orthonormal with det +1, or its "
                         "last row is not 0, 0, 0, 1)")
    return T
