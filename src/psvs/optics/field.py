"""Sample pixels of the camera's field: its outer boundary (the pixels' outer edges) and a grid inside."""
from __future__ import annotations

import numpy as np

from psvs.optics.rig import Camera


def field_pixels(camera: Camera, per_side: int = 65, interior: int = 9) -> np.ndarray:
    """Pixel positions (N, 2), px, on the border of the field (outer pixel edges, ``per_side`` samples a
    side, corners included) plus an ``interior`` x ``interior`` grid inside it."""
    w, h = camera.image_size_px
    u0, u1, v0, v1 = -0.5, w - 0.5, -0.5, h - 0.5
    us, vs = np.linspace(u0, u1, per_side), np.linspace(v0, v1, per_side)
    border = np.concatenate([
        np.stack([us, np.full_like(us, v0)], 1), np.stack([us, np.full_like(us, v1)], 1),
        np.stack([np.full_like(vs, u0), vs], 1), np.stack([np.full_like(vs, u1), vs], 1)])
    gu, gv = np.meshgrid(np.linspace(u0, u1, interior), np.linspace(v0, v1, interior))
    return np.concatenate([border, np.stack([gu.ravel(), gv.ravel()], 1)])
