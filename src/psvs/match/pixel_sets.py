"""Sets of edge pixels (indices into a :class:`psvs.match.edges.EdgePixels`) as psvs.match.auto pairs them:
distinct rows, distinct indices, 8-connected runs along an edge, and indices grouped by label."""
from __future__ import annotations

import cv2
import numpy as np

from psvs.match.edges import EdgePixels


def n_rows(v: np.ndarray) -> int:
    """Number of distinct rows among row indices v (bincount: no hashing, no sort)."""
    return int(np.count_nonzero(np.bincount(v))) if len(v) else 0


def distinct(idx: np.ndarray, n: int) -> np.ndarray:
    """Sorted distinct values of integer indices in [0, n) (a mask, not a hash)."""
    m = np.zeros(n, dtype=bool)
    m[idx] = True
    return np.flatnonzero(m)


def runs(px: EdgePixels, idx: np.ndarray) -> list[np.ndarray]:
    """Split edge pixels ``idx`` into 8-connected runs (lists of indices)."""
    if len(idx) == 0:
        return []
    u, v = px.u[idx], px.v[idx]
    u0, v0 = u.min(), v.min()
    mask = np.zeros((v.max() - v0 + 1, u.max() - u0 + 1), dtype=np.uint8)
    mask[v - v0, u - u0] = 1
    _, lab = cv2.connectedComponents(mask, connectivity=8)
    run_of = lab[v - v0, u - u0]
    order = np.argsort(run_of, kind="stable")
    cuts = np.flatnonzero(np.diff(run_of[order])) + 1
    return np.split(idx[order], cuts)


def row_span(px: EdgePixels, run: np.ndarray) -> int:
    """Rows spanned by edge pixels ``run``, first to last."""
    return int(px.v[run].max() - px.v[run].min() + 1)


def long_runs(px: EdgePixels, pixels: np.ndarray, min_run: int) -> list[np.ndarray]:
    """The 8-connected runs of the distinct edge pixels among ``pixels`` (indices into ``px``) that span at
    least ``min_run`` rows."""
    return [r for r in runs(px, distinct(pixels, len(px.u))) if row_span(px, r) >= min_run]


def joined(runs: list[np.ndarray]) -> np.ndarray:
    """The pixels of all ``runs``, one index array."""
    return np.concatenate(runs) if runs else np.zeros(0, int)


def by_label(labels: np.ndarray, n_labels: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices sorted by label, and where each label's run starts (n_labels + 1 offsets): the entries
    with label i are ``order[start[i]:start[i + 1]]``."""
    order = np.argsort(labels, kind="stable")
    return order, np.searchsorted(labels[order], np.arange(n_labels + 1))
