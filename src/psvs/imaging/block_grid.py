"""JPEG's 8 x 8 block grid in an image: how much stronger its grey-level steps are across the block borders
than between them.

A JPEG frame compressed hard carries a grid of steps every 8 px, fixed to the image, in both views alike. In a
complex image that grid correlates with itself at every lag a multiple of 8 px, and a dense search is pulled
there: the built-in textured scene saved at quality 10 had 95192 of its trusted pixels at 96 px (the
backdrop's true disparity 97.8 px), 33 % of them more than 2 % off against 3.3 % for the PNG (quality 30:
12 %, 50: 5.6 %, 75 and 90: 4.3 %; an adversarial trial). The grid's strength, the mean |step| between
columns 8k+7 and 8k+8 (at whichever phase of 8 steps most: a crop moves the grid) over the mean |step| at the
other phases, or the same for the columns' median |step| when smaller (and the same across rows, the larger of
the two), is about 1.0 on an image without it (there is no reason for the scene's steps to prefer one phase of
8), 1.09 at quality 90, 1.23 at 75, 1.46 at 50, 1.69 at 30 and 2.83 at 10. The median keeps a scene whose own
edges fall on one phase of 8 from passing for a grid (stripes of 24-48 px had 4.5-24, the Fig. 9 pattern 1.7,
now 1.0-1.06: a grid lifts every border, a scene's edges only some).
"""
from __future__ import annotations

import numpy as np

from psvs.errors import MeasurementError

__all__ = ["BLOCK_GRID_LIMIT", "block_grid_refusal", "block_grid_strength", "check_block_grid"]

#: A grid stronger than this is refused: the answers lean to its lags (quality 30, 1.70: 12 % of the trusted
#: pixels more than 2 % off; quality 50, 1.46: 5.6 %, within what a PNG of the scene gives twice over).
BLOCK_GRID_LIMIT = 1.5
BLOCK_PX = 8
#: The fewest borders a phase of 8 must have along an axis for that axis to be judged (49 px): with fewer, one
#: edge makes a phase (a trial's 16 x 16 px PNG was refused as carrying the grid, 1.62).
MIN_BORDERS = 6


def _ratio(steps: np.ndarray) -> float:
    """The grid's strength along one axis from the |steps| (H, W-1 along axis 1); 1.0 when flat or when the
    axis holds fewer than :data:`MIN_BORDERS` borders a phase. At the phase of 8 whose mean |step| is the
    strongest (not index 7 mod 8: a frame cropped by other than a multiple of 8 px moves the grid; a crop of
    3 px put its borders at index 4 mod 8), the smaller of two ratios: its mean |step| over the other phases',
    and its columns' median |step| over the other phases' columns' (each column's |step| averaged over the
    rows first). A grid lifts every border, so both; a scene's edges that fall on one phase of 8 lift the mean
    only (stripes whose period is a multiple of 8 px, a pattern's outlines: trials' lossless PNGs of 48 px
    stripes, 16, and of the Fig. 9 pattern, 1.7, were refused as carrying JPEG's grid)."""
    col = steps.mean(axis=0)
    if col.size < MIN_BORDERS * BLOCK_PX:
        return 1.0
    phase = np.arange(col.size) % BLOCK_PX
    means = np.array([col[phase == k].mean() for k in range(BLOCK_PX)])
    k = int(np.argmax(means))
    ratios = []
    for top, rest in ((float(means[k]), float(np.delete(means, k).mean())),
                      (float(np.median(col[phase == k])), float(np.median(col[phase != k])))):
        ratios.append(top / rest if rest > 0 else (np.inf if top > 0 else 1.0))
    return float(min(ratios))


def block_grid_strength(image) -> float:
    """The 8 x 8 block grid's strength in a grey image (H, W) (module docstring): 1.0 without a grid, larger
    with one; the larger of its two axes' (:func:`_ratio`), 1.0 along an axis too short to judge."""
    a = np.asarray(image, dtype=np.float32)
    if a.ndim != 2:
        return 1.0
    return max(_ratio(np.abs(np.diff(a, axis=1))), _ratio(np.abs(np.diff(a, axis=0)).T))


def block_grid_refusal(image) -> str:
    """Why the image's block grid refuses a dense answer on it (stronger than :data:`BLOCK_GRID_LIMIT`), in
    the words ``psvs disparity`` and the page say; "" when it does not."""
    strength = block_grid_strength(image)
    if strength <= BLOCK_GRID_LIMIT:
        return ""
    times = f"{strength:.2f} times those between" if np.isfinite(strength) else "all there, none between"
    return (f"the image carries JPEG's 8 px block grid: its grey-level steps across the block borders are "
            f"{times} (a frame without it 1.0; a dense answer is pulled to the grid's "
            f"lags beyond {BLOCK_GRID_LIMIT:g}): save the frames at JPEG quality 75 or more, or as PNG")


def check_block_grid(image) -> None:
    """MeasurementError (:func:`block_grid_refusal`'s words) when the image carries a block grid stronger than
    :data:`BLOCK_GRID_LIMIT`."""
    reason = block_grid_refusal(image)
    if reason:
        raise MeasurementError(reason)
