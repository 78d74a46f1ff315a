"""What the seam sensor measures and what the controller makes of it: one frame's groove edges
(:class:`SeamObservation`, frame C) and the groove root fitted to them (:class:`SeamPoint`).

Both the sensor (psvs.robot.sensor) and the controller (psvs.robot.controller) import these; neither
imports the other.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class SeamObservation:
    """One frame's measurement. ``edges_mm``: the two groove edges' triangulated points, each (N, 3)
    frame C, mm (empty when invalid); ``centre_px``: (u, v) of the groove centre in the left view;
    ``reason``: why the frame is invalid ('' when valid); the twin band's disparity and the groove's
    half width on the seed row, px."""

    valid: bool
    edges_mm: tuple[np.ndarray, np.ndarray]
    centre_px: tuple[float, float]
    reason: str = ""
    disparity_px: float | None = None
    half_width_px: float | None = None

    @classmethod
    def invalid(cls, centre_px: tuple[float, float], reason: str) -> "SeamObservation":
        """A frame without a usable groove: no points, the centre tracked so far, and why."""
        return cls(False, (np.empty((0, 3)), np.empty((0, 3))), centre_px, reason)


@dataclass(frozen=True)
class SeamPoint:
    """The seam (groove root) at one frame, base frame: point (3,) mm, unit tangent (3,), groove width mm."""

    point_mm: np.ndarray
    tangent: np.ndarray
    width_mm: float


def fit_seam_point(edge_a: np.ndarray, edge_b: np.ndarray, depth_mm: float, up: np.ndarray) -> SeamPoint:
    """The root of a V-groove from its two edges (each (N, 3) mm, same frame): a quadratic fit of each edge
    along the seam direction (no chord bias on curved seams) evaluated at the middle; the root lies
    ``depth_mm`` below the edges' midpoint along ``up`` (the groove's depth as the joint drawing gives it,
    measured along the torch axis)."""
    mean = np.vstack([edge_a, edge_b]).mean(axis=0)
    # the seam direction: principal axis of both edges, each about its own centre (not across the groove)
    _, _, vt = np.linalg.svd(np.vstack([edge_a - edge_a.mean(axis=0), edge_b - edge_b.mean(axis=0)]),
                             full_matrices=False)
    t = vt[0] * np.sign(vt[0] @ (edge_a[-1] - edge_a[0]) or 1.0)
    fits = []
    for e in (edge_a, edge_b):
        tau = (e - mean) @ t
        deg = 2 if np.ptp(tau) > 3.0 and len(e) >= 6 else 1
        coef = [np.polyfit(tau, e[:, k], deg) for k in range(3)]
        fits.append((np.array([np.polyval(c, 0.0) for c in coef]),
                     np.array([np.polyval(np.polyder(c), 0.0) for c in coef])))
    (pa, da), (pb, db) = fits
    tangent = (da + db) / np.linalg.norm(da + db)
    root = (pa + pb) / 2 - depth_mm * np.asarray(up, float)
    return SeamPoint(root, tangent, float(np.linalg.norm(pa - pb)))
