"""The self-check while the sensor works: a rolling estimate of the twins' row offsets from the frames a
running sensor processes anyway (``psvs live``; docs/health.md).

A whole frame's check costs a few hundred ms (each tile a correlation); a sensor's frame a few tens. So a
rolling check reads a few of a frame's tiles (:data:`TILES_PER_STEP`, in turn over the frame: a sweep of the
field takes a few steps), only when it has the time: each frame adds :data:`SHARE` of the sensor's own time
on it to a credit, and a step runs when the credit covers what a step costs (the median of the last five,
measured as they run; the grids' maps are made once, before the first), its time then taken off the credit:
over a run the check costs at most that share of the sensor's time, give or take one step. The tiles of the
last sweep (one per place of the field; older ones are dropped, so a rig that moves is seen within a sweep)
are judged together as ``psvs check`` judges a frame's (:func:`psvs.health.check.judge`): the same field,
uncertainty and verdict, ``cannot judge`` until enough tiles are in. The steps' frames of a scene that stood
still between them (:meth:`RollingCheck.scene_of`: their band-passed thumbnails correlate) are one view of
it: a tile's neighbour read in the next frame shares its texture, and their evidence is counted once.
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np

from psvs.dense.rig_cache import rectification
from psvs.health.check import TOLERANCE_PX, HealthCheck, checked_tolerance, judge, load_solvers
from psvs.health.rows import band_pass, frame_tiles
from psvs.io.jsonsafe import json_safe
from psvs.optics.rig import Rig

#: The share of the sensor's own frame time the rolling check may take, on average: 8 %, so that with what it
#: costs the sensor beside its own time (caches it evicts: 1-3 % of a tracking run's wall time, measured in
#: bench/bench_live.py) a run takes at most 10 % longer.
SHARE = 0.08
#: Tiles read per step.
TILES_PER_STEP = 12
#: The credit saved up is at most this many steps' cost: a slow frame (a first one's set-up) buys no burst.
MAX_CREDIT_STEPS = 1.5
#: Two steps' frames whose band-passed thumbnails correlate by this much show the scene as it stood.
STILL_NCC = 0.5
#: The first steps' cost is not known: the credit must cover this much (s) before the first one runs.
FIRST_COST_S = 0.03


def still_thumbnail(image) -> np.ndarray:
    """A frame (H, W) shrunk 4 times (area average) and band-passed (psvs.health.rows.band_pass): what a
    still scene's frames share and a moved one's do not."""
    a = np.asarray(image, dtype=np.float32)
    small = cv2.resize(a, (max(a.shape[1] // 4, 1), max(a.shape[0] // 4, 1)), interpolation=cv2.INTER_AREA)
    return band_pass(small)


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    """The normalised cross-correlation of two arrays of one shape (0 when either is flat)."""
    a, b = a - a.mean(), b - b.mean()
    den = float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
    return float(np.sum(a * b)) / den if den > 0 else 0.0


def health_record(check: HealthCheck, frame: int, cost_share: float) -> dict:
    """A judgement as a recording's /psvs/health record (``psvs live`` and ``psvs track``): the frame, verdict,
    field RMS and uncertainty (px), tiles and the check's share of the sensor's time so far."""
    return {"frame": frame, "verdict": check.verdict, "row_offset_rms_px": check.row_offset_rms_px,
            "uncertainty_px": check.uncertainty_px, "tiles": check.tiles, "cost_share": cost_share}


@dataclass(frozen=True)
class HealthEvent:
    """A change of verdict the sensor should say: ``frame`` (index), ``check`` the new verdict's figures,
    ``line`` one line for the terminal."""

    frame: int
    check: HealthCheck
    line: str


class RollingCheck:
    """A rolling self-check of ``rig`` over near..far mm (module docstring). Call :meth:`step` with each frame
    and the time (s) the sensor spent on it; :attr:`latest` is the last judgement (None until the first),
    :attr:`spent_s` and :attr:`sensor_s` the check's and the sensor's time so far, :attr:`last_step_s` the
    last step's: the check's time is at most its share of the sensor's plus that one step's (a step runs only
    on credit, and what it costs beyond is owed by the next)."""

    def __init__(self, rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0,
                 tolerance_px: float = TOLERANCE_PX, share: float = SHARE):
        if not 0 < share <= 1:
            raise ValueError(f"the rolling check's share of the frame time must be in (0, 1], got {share}")
        checked_tolerance(tolerance_px, rig)
        self.rig, self.near_mm, self.far_mm, self.tolerance_px, self.share = rig, near_mm, far_mm, tolerance_px, share
        self.latest: HealthCheck | None = None
        self.spent_s = self.sensor_s = self.idle_spent_s = self.last_step_s = 0.0
        self.steps = self.idle_steps = 0
        self._credit, self._next = 0.0, 0
        self._of_tiles = 0
        self._costs: deque = deque([FIRST_COST_S], maxlen=5)
        self._window: deque = deque()
        self._scenes: deque = deque()
        self._thumb, self._scene = None, 0
        self._said = "healthy"
        rectification(rig, near_mm, far_mm)      # the grids' maps are set-up, as the sensors' own: not a step's
        load_solvers()                            # so are the fit's SciPy modules (their first import)

    def step(self, image, frame: int, sensor_s: float) -> HealthEvent | None:
        """Take frame ``frame`` (its image (H, W) and the sensor's time on it, s) into the estimate when the
        credit allows; a :class:`HealthEvent` when the verdict crosses between healthy and drifted."""
        return self.take(image, frame) if self.due(sensor_s) else None

    def due(self, sensor_s: float) -> bool:
        """Count the sensor's time on a frame (s) into the credit; whether a step is due on that frame (then call
        :meth:`take` with it, e.g. once a frame only a step needs is read)."""
        self.sensor_s += max(sensor_s, 0.0)
        cost = float(np.median(self._costs))
        self._credit = min(self._credit + self.share * max(sensor_s, 0.0), MAX_CREDIT_STEPS * cost)
        return self._credit >= cost

    def take(self, image, frame: int, idle: bool = False) -> HealthEvent | None:
        """One step on frame ``frame`` (its image (H, W)): its next tiles into the last sweep, judged; its time
        taken off the credit. With ``idle`` the step runs on time the sensor does not need (a tracking run's
        run-in, psvs.robot.drift), whether or not a step is due: its time is counted apart
        (:attr:`idle_spent_s`), neither taken off the credit nor in :attr:`cost_share`. A :class:`HealthEvent`
        when the verdict crosses between healthy and drifted."""
        t0 = time.perf_counter()
        tiles = frame_tiles(image, self.rig, self.near_mm, self.far_mm, subset=(self._next, TILES_PER_STEP))
        self._next = (self._next + TILES_PER_STEP) % max(tiles.of_tiles, 1)
        self._of_tiles = tiles.of_tiles
        self._window.append(tiles)
        self._scenes.append(self.scene_of(image))
        while sum(len(t.accepted) for t in self._window) - len(self._window[0].accepted) >= tiles.of_tiles:
            self._window.popleft()                   # the last sweep: one tile per place of the field
            self._scenes.popleft()
        self.latest = judge(list(self._window), self.tolerance_px, list(self._scenes))
        spent = time.perf_counter() - t0
        self.spent_s += spent
        self.last_step_s = spent
        self.steps += 1
        if idle:
            self.idle_spent_s += spent
            self.idle_steps += 1
        else:
            self._credit -= spent
        self._costs.append(spent)
        return self._event(frame)

    def scene_of(self, image) -> int:
        """Which view of the scene this step's frame (H, W) is: the last step's when their band-passed
        thumbnails correlate by :data:`STILL_NCC` or more (the scene stood still: its tiles share texture
        with the last frame's neighbours), else a new one."""
        thumb = still_thumbnail(image)
        if self._thumb is None or thumb.shape != self._thumb.shape or _ncc(thumb, self._thumb) < STILL_NCC:
            self._scene += 1
        self._thumb = thumb
        return self._scene

    def _event(self, frame: int) -> HealthEvent | None:
        c = self.latest
        if c.verdict == "cannot judge" or c.verdict == self._said:
            return None
        self._said = c.verdict
        if c.verdict == "drifted":
            line = (f"frame {frame}: the calibration has drifted: {c.reason} (psvs check on a few frames to "
                    f"confirm, psvs refit to put it back)")
        else:
            line = f"frame {frame}: the calibration holds again: {c.reason}"
        return HealthEvent(frame, c, line)

    def summary(self) -> dict:
        """The latest judgement for a display (JSON-ready, NaN as None): ``verdict`` (None before the first
        step), ``reason``, ``row_offset_rms_px``, ``uncertainty_px``, ``tiles``, ``tolerance_px``, ``steps``,
        ``idle_steps`` (of them, on idle time) and ``cost_pct`` (the check's time over the sensor's, %, the idle
        steps' left out)."""
        c = self.latest
        figures = {} if c is None else {"row_offset_rms_px": c.row_offset_rms_px, "uncertainty_px": c.uncertainty_px}
        return json_safe({"verdict": None if c is None else c.verdict, "reason": "" if c is None else c.reason,
                          "row_offset_rms_px": None, "uncertainty_px": None, **figures,
                          "tiles": 0 if c is None else c.tiles, "tolerance_px": self.tolerance_px,
                          "steps": self.steps, "idle_steps": self.idle_steps,
                          "cost_pct": 100 * self.cost_share})

    @property
    def swept(self) -> bool:
        """Whether the steps so far have read every place of the field once (a whole sweep)."""
        return self._of_tiles > 0 and self.steps * TILES_PER_STEP >= self._of_tiles

    @property
    def cost_share(self) -> float:
        """The check's time over the sensor's, so far (steps on idle time left out)."""
        return (self.spent_s - self.idle_spent_s) / self.sensor_s if self.sensor_s > 0 else 0.0
