"""Do a pair's twins share their rows? The rig says a point's two views lie on one row (of the rectified
views on a build); an edge pair found row by row cannot tell by itself, because a per-row disparity absorbs
a vertical shift wherever the edge is steep. Its curved parts can: shifted by the wrong rows, the twin of a
curve no longer lies along the edge at a smoothly varying disparity.

For each vertical shift s in -S..S px the left edge's pixels are paired with the right edge's on the row
s below, at a disparity linear along the edge (fitted, then refitted on its own pairs), and the pixels
within 1 px of it are counted. A true twin counts most at s = 0 (a steep straight edge, the same at every
s: the aperture problem, which says nothing). A pair counting decisively more, by ``margin`` pixels, at
|s| >= 2 than at 0 is not a twin on this rig's rows: the rig does not fit the image (a knocked mirror, or
another rig), or two look-alike objects sit at different heights. psvs.match.auto refuses such pairs, and
the whole image when no pair shows the rig's rows hold (docs/right-or-refuse.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: px: the largest vertical shift tried (a knocked mirror moves rows by a few px, psvs.health).
MAX_SHIFT_PX = 6
#: px: a shift this large or more is "off"; +-1 px is the edge map's own rounding.
OFF_SHIFT_PX = 2
#: The share of the best count a shift must win by to decide (and ``min_rows`` pixels at least).
DECISIVE_SHARE = 0.2


def _nearest_offsets(keys: np.ndarray, stride: int, u: np.ndarray, v: np.ndarray, reach: int) -> np.ndarray:
    """(N,) the column offset k (|k| <= reach) to the right edge pixel nearest to (u, v) along row v, float NaN
    where none lies within ``reach``; ``keys``: the right pixels' v * stride + u, sorted (stride > every
    column + reach, so a row's keys never reach another's); u, v (N,) int."""
    if len(keys) == 0:
        return np.full(len(u), np.nan)
    q = v * stride + u
    at = np.searchsorted(keys, q)
    after = keys[np.minimum(at, len(keys) - 1)] - q
    before = keys[np.maximum(at - 1, 0)] - q
    after = np.where((at < len(keys)) & (after <= reach), after, np.iinfo(np.int64).max)
    before = np.where((at > 0) & (before >= -reach), before, np.iinfo(np.int64).max)
    k = np.where(np.abs(before) <= after, before, after)      # ties go left, like the nearest-first scan
    inside = (u >= reach) & (u < stride - reach)                # the reach stays on the query's row
    return np.where((np.abs(k) <= reach) & inside, k, np.nan)


def shift_counts(left_uv: tuple[np.ndarray, np.ndarray], right_uv: tuple[np.ndarray, np.ndarray], d_px: float,
                 max_shift: int = MAX_SHIFT_PX) -> np.ndarray:
    """(2 max_shift + 1,) int: for each vertical shift s = -max_shift..max_shift px, how many left edge pixels
    (``left_uv``: (u, v) (N,) int) have a right edge pixel (``right_uv``, (M,) int, negative = unseen) on row
    v + s within 1 px of a disparity linear in v, first near ``d_px`` (px) then fitted to the pixels found."""
    lu, lv = (np.asarray(a, dtype=np.int64) for a in left_uv)
    ru, rv = (np.asarray(a, dtype=np.int64) for a in right_uv)
    seen = (ru >= 0) & (rv >= 0)
    ru, rv = ru[seen], rv[seen]
    if len(lu) < 3 or len(ru) == 0:
        return np.zeros(2 * max_shift + 1, dtype=np.int64)
    reach0 = 2 * max_shift
    shift_u = int(reach0 + abs(d_px) - min(lu.min(), ru.min())) + 2      # every column >= 0, with its reach
    stride = int(max(lu.max(), ru.max()) + shift_u + 2 * reach0 + abs(d_px)) + 2
    keys = np.sort(rv * stride + ru + shift_u)
    lu = lu + shift_u
    shifts = np.arange(-max_shift, max_shift + 1)[:, None]
    rows = lv[None, :] + shifts                                       # (K, N): each shift's rows
    x = np.broadcast_to((lv - lv.mean()).astype(float), rows.shape)
    disp = np.full(rows.shape, float(d_px))
    for reach in (reach0, 2, 2):       # find the twin near d (its median), then near each shift's fitted line
        k = _nearest_offsets(keys, stride, np.rint(lu - disp).astype(np.int64), rows, reach)
        w = np.isfinite(k)
        n = w.sum(axis=1)
        if reach == reach0:
            mid, some = np.full(len(n), float(d_px)), n >= 3       # (a shift that found nothing keeps d)
            if some.any():
                mid[some] = np.nanmedian(np.where(w, disp - k, np.nan)[some], axis=1)
            disp = np.broadcast_to(mid[:, None], disp.shape)
            continue
        y = np.where(w, disp - np.nan_to_num(k), 0.0)                # the disparities found
        sx, sy = (w * x).sum(axis=1), y.sum(axis=1)
        sxx, sxy = (w * x * x).sum(axis=1), (w * x * y).sum(axis=1)
        det = n * sxx - sx * sx
        ok = (n >= 3) & (det > 1e-9 * np.maximum(n * sxx, 1.0))
        slope = np.where(ok, (n * sxy - sx * sy) / np.where(ok, det, 1.0), 0.0)
        mean = np.where(n > 0, (sy - slope * sx) / np.maximum(n, 1), d_px)
        fitted = mean[:, None] + slope[:, None] * x                  # a vertical edge: its mean disparity
        disp = np.where((n >= 3)[:, None], fitted, disp)
    k = _nearest_offsets(keys, stride, np.rint(lu - disp).astype(np.int64), rows, 1)
    return np.isfinite(k).sum(axis=1).astype(np.int64)


@dataclass(frozen=True)
class RowShift:
    """A pair's :func:`shift_counts` read: ``shift`` px the best vertical shift, ``counts`` per shift, and
    ``verdict``: "fit" (decisively best at 0), "off" (decisively best at |shift| >= 2 px), or "flat" (the
    edge cannot tell: steep and straight)."""

    shift: int
    counts: tuple[int, ...]
    verdict: str

    @property
    def at_zero(self) -> int:
        return self.counts[len(self.counts) // 2]

    @property
    def at_shift(self) -> int:
        return self.counts[len(self.counts) // 2 + self.shift]


def row_shift(counts: np.ndarray, min_rows: int) -> RowShift:
    """Read :func:`shift_counts` ``counts`` (2S + 1,): the shifts within 1 px of the rows (the edge map's
    rounding) against those 2 px or more off them; one side decides when its best counts more than the
    other's best by max(``min_rows``, :data:`DECISIVE_SHARE` of its count)."""
    counts = np.asarray(counts, dtype=np.int64)
    shifts = np.arange(len(counts)) - len(counts) // 2
    off = np.abs(shifts) >= OFF_SHIFT_PX
    on_best = int(np.argmax(np.where(off, -1, counts)))
    off_best = int(np.argmax(np.where(off, counts, -1))) if off.any() else on_best
    near, far = int(counts[on_best]), int(counts[off_best]) if off.any() else 0
    if far >= near + max(min_rows, DECISIVE_SHARE * far):
        best, verdict = off_best, "off"
    elif near >= far + max(min_rows, DECISIVE_SHARE * near):
        best, verdict = on_best, "fit"
    else:
        best, verdict = on_best, "flat"
    return RowShift(int(shifts[best]), tuple(int(c) for c in counts), verdict)


@dataclass
class RowCheck:
    """What the pairs of one image said of the rig's rows: how many decisively fit them, and the pairs
    refused as off them (each a :class:`RowShift` and its disparity, px)."""

    fits: int = 0
    off: list[tuple[float, RowShift]] = field(default_factory=list)

    @property
    def refuses(self) -> bool:
        """The image is refused: some pair stands off the rows and none shows that they hold."""
        return bool(self.off) and self.fits == 0

    def describe(self) -> str:
        """One clause: the pairs off their rows, the largest first, with their counts."""
        d, worst = max(self.off, key=lambda o: o[1].at_shift)
        return (f"{len(self.off)} edge pair(s) line up {worst.shift:+d} rows off the rig's rows, none on them "
                f"(the strongest, at disparity {d:.0f} px, agrees on {worst.at_shift} px shifted, "
                f"{worst.at_zero} px on its rows): the rig does not fit this image -- a mirror moved, or "
                f"another rig (psvs check)")


def check_pair(left_px: np.ndarray, px, d_px: float, min_rows: int) -> RowCheck:
    """The :class:`RowCheck` of one pair found from a seed: the whole edges holding its integer left pixels
    ``left_px`` (K, 2) (u, v) (the pair holds only the pixels that found a twin on their own row) against
    every edge pixel as the right view sees it, at disparity ``d_px``; ``px``: the edge map's
    :class:`psvs.match.edges.EdgePixels`."""
    (lu, lv), (ru, rv) = px.left_uv, px.right_uv
    left = np.rint(np.asarray(left_px, dtype=float)).astype(np.int64)
    stride = int(max(lu.max(initial=0), left[:, 0].max(initial=0))) + 2
    on_pair = np.isin(lv * stride + lu, left[:, 1] * stride + left[:, 0]) & (lu >= 0) & (lv >= 0)
    edges = np.isin(px.label, px.label[on_pair])
    rs = row_shift(shift_counts((lu[edges], lv[edges]), (ru, rv), d_px), min_rows)
    return RowCheck(int(rs.verdict == "fit"), [(float(d_px), rs)] if rs.verdict == "off" else [])
