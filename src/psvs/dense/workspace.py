"""Cost volumes kept from one call of :func:`psvs.dense.disparity.dense_disparity` to the next."""
from __future__ import annotations

import math

import numpy as np


class Workspace:
    """The cost volumes of :func:`~psvs.dense.disparity.dense_disparity`, kept from one call to the next (a
    live loop): fresh memory costs page faults on every frame. One per thread (not thread-safe); it holds
    five volumes of (H, W, searched disparities) float32 at the working scale, each as large as the largest
    asked for (a pruned search asks for fewer lags from frame to frame), and those of the coarse pass; with
    a pyramid (psvs.dense.pyramid) its coarse level's and the finer levels' band volumes (costs and sums
    of both maps, (2, H, W, band lags) each, as large as the finest level's)."""

    def __init__(self):
        self._buffers: dict[str, np.ndarray] = {}
        self._coarse: Workspace | None = None

    def array(self, name: str, shape: tuple) -> np.ndarray:
        """A contiguous float32 array of ``shape`` (contents undefined) in the kept buffer ``name``, which
        grows when too small."""
        size = math.prod(shape)
        buf = self._buffers.get(name)
        if buf is None or buf.size < size:
            buf = self._buffers[name] = np.empty(size, np.float32)
        return buf[:size].reshape(shape)

    @property
    def coarse(self) -> Workspace:
        """The workspace of the coarse pass that prunes the search (psvs.dense.prune)."""
        if self._coarse is None:
            self._coarse = Workspace()
        return self._coarse


def volume(workspace: Workspace | None, name: str, shape: tuple) -> np.ndarray:
    """A contiguous float32 array of ``shape``: the buffer ``name`` of ``workspace``, or fresh memory
    without one."""
    return workspace.array(name, shape) if workspace is not None else np.empty(shape, np.float32)
