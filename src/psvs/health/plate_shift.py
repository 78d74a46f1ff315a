"""The row offset a rig makes itself on the paper's geometry: the M1 plate's shift of the left view's rows.

On a build the check reads the twins on the two views' rectified grids, made through the rig (the plate
included): a twin stands on its own row there, to the rectification's residual. On the paper's geometry (no
rectification: psvs.health.rows reads the complex image's own rows) the plate shifts the left view's rows by
up to about 0.3 px near the working range's near end (0.285 px at 420 mm on the default rig; eq. 15's terms
across the rows), and with ``--tolerance-px 0.15`` walls at 400-550 mm read "drifted 0.21-0.30 px" though
nothing moved. :func:`rig_row_offsets` predicts that offset for each tile from the left view's ray alone:
the point on the ray of the tile's centre whose right-view column lies the measured disparity away, projected
into the right view; its row minus the tile's is what the rig itself makes (psvs.match.correspondence's
``correct_rows`` does as much per edge pair, through both pixels, which would take a drift in with the right
one). The check judges what is left (:func:`psvs.health.check.judge`).
"""
from __future__ import annotations

import numpy as np

from psvs.optics.project import project_points
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels

#: Depths (mm along the ray, from its last mirror) the ray is sampled at, geometric: the right view's column
#: is monotonic in depth and its row smooth, so a linear reading between samples holds to 1e-4 px.
SAMPLES = np.geomspace(50.0, 50000.0, 97)


def rig_row_offsets(rig: Rig, centre_px: np.ndarray, disparity_px: np.ndarray) -> np.ndarray:
    """Right view's row minus the left's (px, (n,)) that ``rig`` itself gives a point seen at the left pixels
    ``centre_px`` (n, 2) with disparities ``disparity_px`` (n,) px (left column minus right): NaN where the
    disparity is not finite, the left ray is blocked, or no point on it shows that disparity."""
    centre = np.asarray(centre_px, dtype=np.float64).reshape(-1, 2)
    d = np.asarray(disparity_px, dtype=np.float64).reshape(-1)
    out = np.full(len(centre), np.nan)
    rays = trace_pixels(centre, rig, "left")
    use = np.flatnonzero(rays.valid & np.isfinite(d))
    if not len(use):
        return out
    pts = rays.origins_mm[use, None, :] + SAMPLES[None, :, None] * rays.dirs[use, None, :]     # (m, s, 3)
    uv, ok = project_points(pts.reshape(-1, 3), rig, "right")
    u = np.where(ok, uv[:, 0], np.nan).reshape(len(use), -1)
    v = np.where(ok, uv[:, 1], np.nan).reshape(len(use), -1)
    target = centre[use, 0] - d[use]                            # the right view's column at that disparity
    for k, i in enumerate(use):
        uk, vk = u[k], v[k]
        good = np.isfinite(uk) & np.isfinite(vk)
        s = np.flatnonzero(good[:-1] & good[1:] & ((uk[:-1] - target[k]) * (uk[1:] - target[k]) <= 0))
        if not len(s):
            continue
        j = s[0]
        t = (target[k] - uk[j]) / (uk[j + 1] - uk[j]) if uk[j + 1] != uk[j] else 0.0
        out[i] = vk[j] + t * (vk[j + 1] - vk[j]) - centre[i, 1]
    return out
