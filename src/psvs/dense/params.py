"""Tuning of the dense method (:func:`psvs.dense.disparity.dense_disparity`) and its two presets.

:data:`DEFAULT` is the full-resolution mode; :data:`FAST` (``params=FAST``, ``--fast`` on the command line)
works at half resolution with plain windows, no guided filter and 4 SGM paths. :data:`COARSE` is the pass
that prunes the default mode's search (psvs.dense.prune).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

#: px: disparities below this cannot be told from the image's own smoothness and are not searched.
MIN_LAG_PX = 3
#: px: the smallest image side accepted (and the smallest side of the half-resolution image).
MIN_SIZE_PX = 16


def searched_lags(d_min: float, d_max: float, width: int) -> tuple[int, int]:
    """The first and last whole-px lag searched for the disparities d_min..d_max (px) on an image ``width`` px
    wide: one lag beyond the whole px that bracket them (from :data:`MIN_LAG_PX` up, below the width), so that
    every disparity of the range has a searched lag on each side of its nearest one and a minimum there is
    placed between them. With the lags inside the range (ceil and floor), a surface at the far end (86.0-87.4
    px with 86.4 asked, 87 searched; 88 in the fast mode's half-resolution lags) was answered at the end's lag
    or 2-3 px inside it (trial, issue 41). An answer on the outer lags lies outside the range asked for and is
    not trusted (:func:`psvs.dense.trust.echo_trust`).

    >>> searched_lags(86.4, 255.1, 640), searched_lags(1.0, 639.5, 640)
    ((85, 257), (3, 639))
    """
    return max(MIN_LAG_PX, math.floor(d_min) - 1), min(math.ceil(d_max) + 1, width - 1)


@dataclass(frozen=True)
class DenseParams:
    """Tuning of :func:`~psvs.dense.disparity.dense_disparity`; lengths in px of the working scale (of a
    pyramid's level: psvs.dense.pyramid)."""

    sigma_px: float = 0.7          # band-pass: image minus its Gaussian blur of this σ
    window: int = 5                # NCC window side
    shift_window: int = 5          # shiftable-window neighbourhood side (1: plain windows)
    guided_radius: int = 4         # guided filter of the echo volume, box radius (0: none)
    guided_eps: float = 0.01       # its regulariser, in (guide units)², the guide being C scaled to 0..1
    aperture_window: int = 7       # side of the patch whose x-share of gradient energy weights the echo
    aperture_share: float = 0.2    # x-share at which a patch counts as fully informative
    p1: float = 0.3                # SGM penalty of a 1 px disparity step (NCC units)
    p2: float = 16.0               # SGM penalty of a larger jump between like neighbours ...
    edge_contrast: float = 0.06    # ... divided by 1 + |ΔC| / this (C blurred, scaled to 0..1) across edges
    n_paths: int = 8               # SGM paths, 4 or 8
    ownership_margin: float = 0.2  # a pixel's own echo may be this much below the other view's and still own it
    scale: int = 1                 # 2: work at half resolution (the fast mode); lengths are at that scale
    second_pass: bool = True       # re-match, from each view's own evidence, pixels the first pass left inconsistent
    median_px: int = 11            # final median filter of each map (odd side; 1 = none): removes the fill's streaks
    prune: bool = True             # full resolution: search only the lags a coarse pass (COARSE) finds in the scene
    pyramid: bool = True           # a large image or range: coarse to fine (psvs.dense.pyramid), else one level
    band_lags: int = 6             # the lags each pixel searches at a finer level of the pyramid
    refine_window: int = 3         # the NCC window side at a finer level (plain windows, no guided filter)
    refine_median_px: int = 11     # the pyramid's final median of each map at the working scale (odd side; 1 = none)
    finest_local_px: int = 3       # the pyramid's working level: costs summed over this window (odd px) and each
    #                                pixel's winner taken, instead of the semi-global aggregation (0)
    top: DenseParams | None = None  # the pyramid's coarse level: these parameters (None: the mode's own, at scale 1)

    def __post_init__(self):
        if self.band_lags < 4:
            raise ValueError(f"band_lags must be >= 4, got {self.band_lags}")
        if self.refine_window < 1 or self.refine_window % 2 == 0:
            raise ValueError(f"refine_window must be an odd number of px, got {self.refine_window}")
        if self.finest_local_px < 0 or (self.finest_local_px and self.finest_local_px % 2 == 0):
            raise ValueError(f"finest_local_px must be 0 or an odd number of px, got {self.finest_local_px}")
        if self.refine_median_px < 1 or self.refine_median_px % 2 == 0:
            raise ValueError(f"refine_median_px must be an odd number >= 1, got {self.refine_median_px}")


#: The default mode: full resolution, shiftable windows, guided filter, 8 paths, second pass, median. With a
#: pyramid its coarse level searches the whole range, unpruned: the pyramid is the pruning, and a coarse pass
#: at half the coarse level's resolution missed cards 150 px wide at the near end of a 1.6 MP build's range
#: (the whole card wrong; tests/dense/test_sweep_wide.py, seed 6), at no cost in time (4.54 % wrong on
#: average over the 1440 façades and a 2.3 MP build against 4.60 % pruned).
DEFAULT = DenseParams(top=DenseParams(prune=False))
#: The fast mode: half resolution, plain 9 x 9 windows, no guided filter, 4 paths, one pass, no median.
#: With a pyramid (a large image or range) its coarse level runs the default mode on 4 paths, pruned (it is
#: small), and the finer levels down to half resolution search their bands on 4 paths, with a 5 x 5 median at the
#: end. (The coarse level on 8 paths was 4 % slower and no better: on four drawn builds of 0.4-2.1 MP
#: (tests/support/rig_draws.py, seeds 1, 3, 6, 7) the wrong share within 0.5 points either way on cards and walls
#: but one 1.5 better with 4 paths, and 0.3-1.7 better on slanted planes with 4. Without its second pass: 15 %
#: faster, but 10-15 points worse on slanted planes.)
FAST = DenseParams(sigma_px=0.5, window=9, shift_window=1, guided_radius=0, n_paths=4, scale=2, second_pass=False,
                   median_px=1, prune=False, refine_median_px=5, finest_local_px=0, top=DenseParams(n_paths=4))
#: The coarse pass that prunes the default mode's search: the fast mode. (At quarter resolution it would
#: take 12 ms instead of 55 at 160 disparities, but it misses a 64 x 64 px object whose disparity stands
#: apart: tests/dense/test_disparity.py.)
COARSE = FAST
