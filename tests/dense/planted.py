"""Planted-truth complex images for the dense tests: a textured background plane and a textured
foreground rectangle, each at one disparity, seen by two rectified views and superimposed."""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter


def texture(h: int, w: int, seed: int, blur_px: float = 1.2) -> np.ndarray:
    """Band-limited random texture in grey levels ~30..225, (h, w); no period, no structure to confuse."""
    rng = np.random.default_rng(seed)
    t = gaussian_filter(rng.standard_normal((h, w)), blur_px)
    return 127.0 + 95.0 * t / np.abs(t).max()


def layered_pair(h=200, w=320, d_bg=18, d_fg=31, rect=(40, 160, 90, 250), seed=0):
    """(left, right, truth_left, truth_right): views (h, w) grey levels and each view's disparity (px).

    Texture coordinates are the left view's columns: the left view shows the foreground inside ``rect``
    (top, bottom, left, right) and the background elsewhere; the right view sees the point of left column
    x at x − d, the nearer surface winning. Left pixels whose twin falls outside the image are NaN in the
    truth, as in the simulator's ground truth."""
    bg = texture(h, w + d_fg + 2, seed)
    fg = texture(h, w + d_fg + 2, seed + 1)
    top, bottom, first, last = rect
    rows = np.arange(h)[:, None]
    cols = np.arange(w)[None, :]
    in_fg = (rows >= top) & (rows < bottom) & (cols >= first) & (cols < last)
    left = np.where(in_fg, fg[:, :w], bg[:, :w])
    truth_left = np.where(in_fg, float(d_fg), float(d_bg))
    truth_left[cols - truth_left < 0] = np.nan
    # right view: column x' sees the foreground if x' + d_fg lies in the rectangle, else the background
    xf = cols + d_fg
    sees_fg = (rows >= top) & (rows < bottom) & (xf >= first) & (xf < last)
    right = np.where(sees_fg, np.take_along_axis(fg, np.broadcast_to(xf, (h, w)), axis=1),
                     np.take_along_axis(bg, np.broadcast_to(cols + d_bg, (h, w)), axis=1))
    truth_right = np.where(sees_fg, float(d_fg), float(d_bg))
    return left, right, truth_left, truth_right
