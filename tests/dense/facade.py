"""High-resolution dense scenes: photo-textured cards before a building façade with large plain panels
and a grid of repeated windows (the structure that a matcher with windows fixed in pixels loses at 5x the
pixels), for the mv1440 rigs over 550-1100 mm."""
from __future__ import annotations

import numpy as np

from psvs.simulate.builtin import photo_texture, pose_at, regulated_light
from psvs.simulate.scene import Scene, SceneObject
from psvs.simulate.textures import ImageTexture

#: mm: the façade's size (width, height); its texture is sampled at this many texels per mm.
FACADE_MM = (1500.0, 1150.0)
TEXELS_PER_MM = 1.0


def facade_texture(seed: int, plain_share: float = 0.3) -> ImageTexture:
    """A façade (FACADE_MM): a gravel-photo render at low contrast, ``plain_share`` of it covered by
    uniform panels (no texture at all, 80 % x 80 % of a bay, a strip of wall
    between them), and a grid of identical windows (a dark
    frame around a brick photo, every one the same) in the other bays. ``seed`` moves the panels and
    the window grid's pitch and phase."""
    rng = np.random.default_rng(seed)
    w, h = (int(s * TEXELS_PER_MM) for s in FACADE_MM)
    gravel = photo_texture("gravel", FACADE_MM).image
    rows = (np.arange(h) * gravel.shape[0] / h).astype(int)
    cols = (np.arange(w) * gravel.shape[1] / w).astype(int) % gravel.shape[1]
    wall = 0.55 + 0.6 * (gravel[rows][:, cols] - gravel.mean())
    brick = photo_texture("brick", (1.0, 1.0)).image
    pitch_x, pitch_y = rng.uniform(170, 230), rng.uniform(180, 240)
    win_w, win_h = 0.55 * pitch_x, 0.6 * pitch_y
    pane = brick[:int(win_h) - 16, :int(win_w) - 16]
    window = np.full((int(win_h), int(win_w)), 0.12)
    window[8:8 + pane.shape[0], 8:8 + pane.shape[1]] = 0.25 + 0.5 * pane
    x0, y0 = rng.uniform(20, pitch_x), rng.uniform(20, pitch_y)
    n_x, n_y = int((w - x0) // pitch_x), int((h - y0) // pitch_y)
    plain = rng.random((n_y, n_x)) < plain_share
    for j in range(n_y):
        for i in range(n_x):
            top, left = int(y0 + j * pitch_y), int(x0 + i * pitch_x)
            if plain[j, i]:   # a plain panel over most of the bay, a strip of wall around it
                t, b = int(top - 0.1 * pitch_y), int(top + 0.7 * pitch_y)
                wall[max(t, 0):b, max(int(left - 0.1 * pitch_x), 0):int(left + 0.65 * pitch_x)] = 0.7
            elif top + window.shape[0] <= h and left + window.shape[1] <= w:
                wall[top:top + window.shape[0], left:left + window.shape[1]] = window
    return ImageTexture(np.clip(wall, 0.0, 1.0), FACADE_MM, f"facade(seed={seed})")


def cards_before_facade(seed: int = 0, facade_mm: float = 1050.0) -> Scene:
    """Two or three photo cards at 600-850 mm, turned a little, before the façade at ``facade_mm``."""
    rng = np.random.default_rng(seed + 100)
    photos = ("astronaut", "coffee", "chelsea", "rocket")
    objs = []
    for k in range(2 + seed % 2):
        z = rng.uniform(600.0, 850.0)
        size = (rng.uniform(110, 170), rng.uniform(80, 120))
        x, y = rng.uniform(-160, 160), rng.uniform(-90, 90)
        objs.append(SceneObject("rectangle", pose_at(x, y, z, rng.uniform(-8, 8), rng.uniform(-20, 20),
                                                 rng.uniform(-5, 5)),
                                photo_texture(photos[(seed + k) % len(photos)], size), size_mm=size, name=f"card{k}"))
    return Scene(tuple(objs), regulated_light(800.0), facade_mm, facade_texture(seed), "cards_facade")
