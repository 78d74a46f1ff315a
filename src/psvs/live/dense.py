"""Dense depth of every live frame: by default the fast mode of psvs.dense (half resolution, 4 SGM paths)
over the rig's working range, on any rig (on a build, on the rectified grids of psvs.dense.build).

Each frame gives the left view's disparity map and, on a grid of every ``stride``-th pixel, the
triangulated points (frame C, mm) and their depth (:func:`psvs.dense.build.rig_cloud`: on a build through
its depth table, :mod:`psvs.dense.depth_table`, made on the first frame or read from the cache folder,
:mod:`psvs.dense.rig_cache`); one pixel in 16 keeps the cloud's shape and its median depth at a sixteenth
of the points to log and send.

Every answer is tested against chance (docs/right-or-refuse.md), at camera rate too: the first frame's maps
get the echo test of ``psvs disparity`` (:func:`psvs.dense.build.rig_trust`), and then every
:data:`TRUST_EVERY`-th frame's (a second at 30 frames/s; the test costs about ten fast maps; counted in frames,
so a video gives the same answers however fast the machine). A frame's cloud and median hold only the pixels
the latest test supported whose answer has moved continuously since, frame to frame, with the scene's motion
(:meth:`DenseSensor._held`), not every answered pixel: on a textureless backdrop the map answers noise (Fig.
5b's median wandered 730-811 mm over 40 noisy frames, its objects at 690-720 mm; now 693-695 mm). A frame
where fewer than :data:`HELD_SHARE` of them hold (the scene changed) is tested at once. Until a test finds the
scene's echo again, a frame has no depth (no points, median NaN; its map is kept). A video of noise gives no
depth, and neither does one whose frames carry a hard JPEG compression's block grid (an MJPEG camera at a low
quality: the test refuses it before asking the echo, in ``psvs disparity``'s words).
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, replace

import numba as nb
import numpy as np

from psvs.dense.build import dense_on_rig, rig_cloud, rig_trust
from psvs.dense.params import FAST, DenseParams
from psvs.dense.separate import rig_views
from psvs.dense.trust import within_disparities
from psvs.dense.workspace import Workspace
from psvs.imaging.block_grid import block_grid_refusal
from psvs.optics.rig import Rig

#: The echo test (whether the scene's echo stands above chance) is made on the first frame and then on every
#: this many-th.
TRUST_EVERY = 30
#: px: a pixel the latest echo test supported keeps that support while its answer stays, frame to frame,
#: within this (or :data:`MOTION_SPREAD`'s tolerance, if larger) of the previous frame's as the scene's motion
#: moves it (the echo test's own tolerance, psvs.dense.trust.TOL_PX); moved further, the scene there changed,
#: and the pixel waits for the next test.
HELD_PX = 1.5
#: When fewer than this share of the latest test's supported pixels hold (the scene moved), the frame is
#: tested again at once.
HELD_SHARE = 0.5
#: The most pixels the motion between two frames is fitted on (evenly chosen among the held ones).
FIT_PIXELS = 20000
#: A held answer's move may stand this many robust spreads (1.4826 MAD) of the moves of all held answers off
#: the scene's motion (and :data:`HELD_PX` always): a fast move spreads the moves of answers that are right.
MOTION_SPREAD = 3.0
#: px: a tolerance beyond this means no smooth motion explains the answers' moves (a cut to another scene
#: spread them by 19 px; the textured scene moving 7.5 mm a frame at 1100 mm on mv1440_misaligned, 1.9-3.1 px):
#: nothing is held.
MAX_MOVE_SPREAD_PX = 4.5


@dataclass(frozen=True, eq=False)
class DenseFrame:
    """One frame's dense result. ``disparity_px`` (H', W') float32: the left map (on a build, on the left
    view's rectified grid), NaN where no answer; ``searched_px`` the disparity range searched;
    ``points_mm`` (N, 3) and ``pixels`` (N, 2) (u, v on the map's grid) of the strided cloud, and
    ``depth_mm`` its depth on the strided grid (every ``stride``-th pixel of the map, NaN where no point);
    ``median_z_mm`` (NaN with no point), ``answered_pct`` (% of the map's pixels with a disparity, 0 when not
    ``supported``, as ``psvs disparity`` counts them), the processing time ``elapsed_s`` and
    ``supported``: whether the latest echo test found the scene's echo beyond chance (without it, no points,
    no depth and nothing answered: the map's disparities are then no measurement); ``mapped``: whether the
    map holds any disparity at all (a featureless frame: none); ``held`` (H', W') bool, the pixels the points
    and median come from (the latest echo test's supported ones that held since; None before a test),
    ``tested`` whether the echo test ran on this frame and ``refusal`` why the latest test supported nothing
    before asking the echo ("" when it asked: a frame whose JPEG block grid pulls the map to the grid's lags,
    :func:`psvs.imaging.block_grid.block_grid_refusal`, is refused as ``psvs disparity`` refuses it)."""

    frame: int
    disparity_px: np.ndarray
    searched_px: tuple[float, float]
    points_mm: np.ndarray
    pixels: np.ndarray
    depth_mm: np.ndarray
    median_z_mm: float
    answered_pct: float
    elapsed_s: float
    supported: bool = True
    mapped: bool = True
    held: np.ndarray | None = None
    tested: bool = False
    refusal: str = ""

    def brief(self) -> "DenseFrame":
        """This frame without its map and cloud (empty arrays): what a run's log and summary keep of every
        frame. A camera runs for as long as it is let, and the maps would fill the memory (1.2 MB a frame at
        640x480: 4 GB an hour at 30 frames/s)."""
        return replace(self, disparity_px=np.zeros((0, 0), np.float32), points_mm=np.zeros((0, 3)),
                       pixels=np.zeros((0, 2)), depth_mm=np.zeros((0, 0)), held=None)


@nb.njit(cache=True, parallel=True)
def _moved_with(held, d, prev, c0, c1, c2, tol, out):  # noqa: PLR0913  # pragma: no cover - compiled
    """out = held & (|d − (c0 + c1 p + c2 p²)| <= tol), p the previous map (all (H, W)), in one pass (NumPy's
    polyval and the comparison made five passes over the map: 15 ms a 1440x1080 frame); its Horner order and
    float64 arithmetic, so the same pixels."""
    h, w = d.shape
    for y in nb.prange(h):
        for x in range(w):
            if held[y, x]:
                p = np.float64(prev[y, x])
                out[y, x] = abs(np.float64(d[y, x]) - (c0 + (c1 + c2 * p) * p)) <= tol   # NaN: False
            else:
                out[y, x] = False


class DenseSensor:
    """Dense depth frame after frame: ``step(frame)`` -> :class:`DenseFrame`. One per thread (it keeps
    the cost volumes between frames).

    Parameters
    ----------
    rig : Rig
    near_mm, far_mm : float
        The working range whose disparities are searched.
    params : DenseParams
        The tuning of psvs.dense: :data:`~psvs.dense.params.FAST` (the default here, camera rate) or
        :data:`~psvs.dense.params.DEFAULT` (the full-resolution mode), or your own.
    stride : int
        Triangulate one pixel in ``stride`` along each axis (>= 1).
    """

    def __init__(self, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0, *, params: DenseParams = FAST,
                 stride: int = 4):
        if not (isinstance(stride, (int, np.integer)) and stride >= 1):
            raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
        if not 0 < near_mm < far_mm:
            raise ValueError(f"the working range needs 0 < near < far, got {near_mm}..{far_mm} mm")
        if not isinstance(params, DenseParams):
            raise TypeError(f"params must be a DenseParams (FAST, DEFAULT or your own), got {params!r}")
        self.rig, self.near_mm, self.far_mm, self.params, self.stride = rig, near_mm, far_mm, params, int(stride)
        self.frames = 0
        self._workspace = Workspace()     # the cost volumes, reused frame after frame
        self._supported = False
        self._refusal = ""                          # why the latest test supported nothing without asking the echo
        self._trusted: np.ndarray | None = None     # the last echo test's trusted pixels of the left map
        self._held_mask: np.ndarray | None = None   # ... those still held in the previous frame
        self._previous: np.ndarray | None = None    # the previous frame's map
        self._last = None                           # the last frame's maps (RigDense), for its views
        self._working = False                       # the working range's disparities (px), once known

    def _held(self, d: np.ndarray) -> np.ndarray | None:
        """(H', W') bool: the pixels the latest echo test supported whose answer has moved continuously since,
        frame to frame, with the scene (a support holds for the answer it was given and what that answer
        smoothly became; where the map answers noise, answers jump); None before a test.

        The scene's motion: d = c0 + c1 d' + c2 d'^2 from the previous frame's d' (a move in depth changes a
        disparity by about its square; a lateral move barely changes it), fitted by least squares on at most
        :data:`FIT_PIXELS` of the held pixels, and refitted twice on those within the tolerance: the larger of
        :data:`HELD_PX` and :data:`MOTION_SPREAD` robust spreads of their moves about it; none when that
        exceeds :data:`MAX_MOVE_SPREAD_PX`."""
        if self._trusted is None or self._trusted.shape != d.shape:
            return None
        prev, held = self._previous, self._held_mask
        pick = np.flatnonzero(held & np.isfinite(d))
        pick = pick[:: max(1, len(pick) // FIT_PIXELS)]
        x, y = prev.ravel()[pick].astype(np.float64), d.ravel()[pick].astype(np.float64)
        poly = np.polynomial.polynomial
        coef, tol = np.array([0.0, 1.0, 0.0]), HELD_PX
        for _ in range(3):
            if len(x) > 10 and np.ptp(x) > 1e-6:
                coef = poly.polyfit(x, y, 2)
            res = np.abs(y - poly.polyval(x, coef))
            tol = max(HELD_PX, MOTION_SPREAD * 1.4826 * float(np.median(res))) if len(res) else HELD_PX
            x, y = x[res <= tol], y[res <= tol]
        if tol > MAX_MOVE_SPREAD_PX:                # no smooth motion explains the moves: another scene
            return np.zeros(d.shape, bool)
        out = np.empty(d.shape, bool)
        _moved_with(held, d, prev, float(coef[0]), float(coef[1]), float(coef[2]), float(tol), out)
        return out

    def step(self, frame) -> DenseFrame:
        """The dense disparity and strided cloud of ``frame`` (H, W) grey."""
        t0 = time.perf_counter()
        with warnings.catch_warnings():    # a featureless frame: no map (``mapped`` false), said per frame
            warnings.simplefilter("ignore", RuntimeWarning)
            dense = dense_on_rig(frame, self.rig, self.near_mm, self.far_mm, params=self.params,
                                 workspace=self._workspace)
        d = dense.result.disparity_left
        held = self._held(d)
        if self._working is False:                  # the working range's disparities (traced once)
            self._working = dense.working_px
        if held is not None and self._working is not None:   # an answer moved out of them is supported no more
            held = within_disparities(held, d, self._working)
        tested = self.frames % TRUST_EVERY == 0 or held is None or held.sum() < HELD_SHARE * self._trusted.sum()
        if tested:                              # due, or the scene changed: tested again
            self._refusal = block_grid_refusal(frame)
            self._trusted = np.zeros(d.shape, bool) if self._refusal else rig_trust(dense).trusted_left
            self._supported = bool(self._trusted.any())
            held = self._trusted
        self._previous, self._held_mask, self._last = d, held, dense
        grid = (slice(self.stride // 2, None, self.stride),) * 2
        mask = np.zeros(d.shape, bool)
        mask[grid] = held[grid]
        cloud = rig_cloud(dense, self.rig, mask=mask)
        z = cloud.points_mm[:, 2]
        finite = np.isfinite(d)
        out = DenseFrame(self.frames, d, dense.result.searched_px, cloud.points_mm, cloud.pixels,
                         cloud.depth_mm[grid], float(np.median(z)) if len(z) else float("nan"),
                         100.0 * float(np.mean(finite)) if self._supported else 0.0,
                         time.perf_counter() - t0, self._supported, bool(finite.any()), held, tested,
                         self._refusal)
        self.frames += 1
        return out

    def views(self, split: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The separated left and right views of the last frame stepped (:func:`psvs.dense.build.rig_views`:
        on a build on the rectified grids; ``split`` instead of the rig's), e.g. for a recording. The view
        separation costs several fast maps: ``psvs live`` records them on the frames the echo test runs on."""
        if self._last is None:
            raise ValueError("no frame stepped yet: the views are the last frame's")
        return rig_views(self._last, self.rig, split)
