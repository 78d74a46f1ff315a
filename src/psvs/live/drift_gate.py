"""No depth through a calibration that its own frames say has moved.

The rolling self-check (psvs.health.rolling) judges, a few tiles a frame, whether the twins still stand on
the rig's rows. While its latest judgement says *drifted*, a live sensor's depth is no measurement: a knock
after the first frame (which the first frame's rows test cannot see) took a still scene's reading from 846.96
to 825.08 mm (-2.6 %), and `psvs live` gave that depth to the 365 frames after the check had said so, exit 0
(trial 44). `psvs live` and the page's live mode withhold it the same way.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

#: What a frame says instead of its depth while the rolling check says the calibration has drifted.
WITHHELD = "no depth: the calibration has drifted (psvs check, psvs refit)"


def drifted(check) -> bool:
    """Whether a self-check's judgement (a :class:`psvs.health.check.HealthCheck`, or None before one) says the
    twins have left their rows."""
    return check is not None and check.verdict == "drifted"


def withheld(step, dstep):
    """A frame's tracker step (:class:`~psvs.live.tracker.TrackStep`) and dense frame
    (:class:`~psvs.live.dense.DenseFrame`), either None, without their depth and their pair or cloud, saying
    :data:`WITHHELD` instead (module docstring)."""
    if step is not None:
        step = replace(step, seed_px=None, pair=None, disparity_px=float("nan"), depth_mm=float("nan"),
                       message=WITHHELD)
    if dstep is not None:
        dstep = replace(dstep, points_mm=np.zeros((0, 3)), pixels=np.zeros((0, 2)),
                        depth_mm=np.full(dstep.depth_mm.shape, np.nan), median_z_mm=float("nan"), answered_pct=0.0,
                        supported=False, refusal=WITHHELD)
    return step, dstep
