"""What the grey image says about an edge and its twin, where the binary edge map cannot tell.

The complex image is the *sum* of the two views, so an edge of one view that falls on a bright object of
the other view still steps the grey level by its own contrast, although both sides of it land above the
binary threshold and the edge map loses it there. Automatic pairing (:mod:`psvs.match.auto`) reads these
steps along the row, I(u + 2) - I(u - 2) (:func:`psvs.match.edges.row_step`): their sign is an edge
pixel's polarity (twins cross the same object boundary the same way), and a step of that sign at a
pixel's twin column shows the twin where the edge map lost it.
"""
from __future__ import annotations

import numpy as np

from psvs.match.edges import EdgePixels, row_step


def polarity(grey: np.ndarray, px: EdgePixels, level: float) -> np.ndarray:
    """Sign (-1, 0, +1) int8 (N,) of the grey step along the row at each edge pixel of ``px``, 0 where
    the step is under ``level`` grey levels. ``grey``: float (H, W), the shape of the edge map."""
    if grey.shape != tuple(px.shape):
        raise ValueError(f"grey must have the edge map's shape {tuple(px.shape)}, got {grey.shape}")
    step = row_step(grey, px.u, px.v)
    return np.where(np.abs(step) < level, 0, np.sign(step)).astype(np.int8)


def step_image(grey: np.ndarray, pad: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`row_step` at every pixel of a float grey (H, W) image, and the headroom above the darker of
    its two samples where the brighter one reaches the image's maximum (a step clipped by saturation), else
    infinity; both zero-padded by ``pad`` columns each side: (H, W + 2 pad), column u at u + pad."""
    h, w = grey.shape
    u, v = np.arange(w)[None, :], np.arange(h)[:, None]
    a, b = grey[v, np.clip(u - 2, 0, w - 1)], grey[v, np.clip(u + 2, 0, w - 1)]
    top = grey.max()
    steps, room = np.zeros((h, w + 2 * pad)), np.zeros((h, w + 2 * pad))
    steps[:, pad:pad + w] = row_step(grey, u, v)
    room[:, pad:pad + w] = np.where(np.maximum(a, b) >= top, top - np.minimum(a, b), np.inf)
    room[:, :pad] = room[:, pad + w:] = np.inf
    return steps, room


def twin_step_seen(steps: tuple[np.ndarray, np.ndarray], px: EdgePixels, idx: np.ndarray, d: float,
                   tol_px: float, level: float, blocked: np.ndarray,
                   view: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Masks (len(idx),) seen and blind, for the twins of edge pixels ``idx`` (taken in ``view``, 0 left or
    1 right) at column u - d px of their rows (+-tol_px; on a build, rows and columns of the rectified
    views, :meth:`EdgePixels.twin_pixels`).

    Seen: the grey image steps the same way there, by at least half as much (and ``level`` grey levels;
    half the headroom where saturation clips the step), and no ``blocked`` pixel lies there: an edge
    already claimed *in the twin's view*. That step is another object's edge in the same view; an edge of
    the *other* view there is what the twin may have merged with. Blind: saturation flattens the whole
    neighbourhood, which can then neither show nor deny the twin. ``steps`` (step, headroom) and
    ``blocked`` (H, W + 2 pad) bool are padded images from :func:`step_image` (same padding).
    """
    step, room = steps
    pad = (step.shape[1] - px.shape[1]) // 2
    u, v = px.u[idx] + pad, px.v[idx]
    own = step[v, u]
    sign = np.sign(own)
    seen = np.zeros(len(idx), dtype=bool)
    other = np.zeros(len(idx), dtype=bool)
    t = int(np.ceil(tol_px))
    blind = np.ones(len(idx), dtype=bool)
    for k in range(-t, t + 1):
        tu, tv, inside = px.twin_pixels(idx, k - np.rint(d), view)
        tu, tv = np.clip(tu + pad, 0, step.shape[1] - 1), np.clip(tv, 0, step.shape[0] - 1)
        step_k = np.where(inside, step[tv, tu], 0.0)            # outside the image: as the zero padding
        room_k = np.where(inside, room[tv, tu], np.inf)
        need = np.maximum(level, 0.5 * np.minimum(np.abs(own), room_k))
        seen |= sign * step_k >= need
        other |= inside & blocked[tv, tu]
        blind &= room_k < level
    return seen & ~other & (sign != 0), blind & ~other
