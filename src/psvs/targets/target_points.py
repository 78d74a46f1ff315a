"""What a detected calibration target is: the target kinds (:data:`Target`), their points in the target's own
frame (:func:`target_points_mm`) and one complex image's detection (:class:`TargetDetection`). Shared by
the circle-grid detector (:mod:`psvs.targets.detect`) and the ChArUco one (:mod:`psvs.targets.charuco`),
which import it and not each other."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psvs.simulate.textures import AsymmetricCircleGrid, CharucoBoard, CircleGrid

Target = CircleGrid | AsymmetricCircleGrid | CharucoBoard


@dataclass(frozen=True, eq=False)
class TargetDetection:
    """One complex image's target points: ids (n,) int, indices into :func:`target_points_mm`; left, right
    (n, 2) px, the same target point in both views; reliable (n,) bool: both images located without bias
    (no neighbour or other view's edge disturbing them; an untrusted point may be several px off: the centre
    of two merged discs); ``complete``: every point of the target found;
    ``ids_certain``: the ids are the target's own (False where part of a symmetric grid fits it at several
    places: the ids are then right up to a shift along the grid, the same in both views)."""

    ids: np.ndarray
    left: np.ndarray
    right: np.ndarray
    reliable: np.ndarray
    complete: bool
    ids_certain: bool = True

    def object_mm(self, target: Target) -> np.ndarray:
        """The points' positions on the target (n, 3) mm, z = 0."""
        local = target_points_mm(target)[self.ids]
        return np.column_stack([local, np.zeros(len(local))])


def target_points_mm(target: Target) -> np.ndarray:
    """The target's calibration points (N, 2) mm in its own frame (centred), in its id order."""
    if isinstance(target, CharucoBoard):
        return target.corners_mm()
    return target.centres_mm()
