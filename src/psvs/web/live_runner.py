"""The web UI's live mode: a background thread that reads frames, tracks the selected edge and/or computes
a dense depth map of each, runs the rolling self-check beside them (psvs.health.rolling: the twins' rows at
a share of the sensors' time), and keeps the latest frame, the latest results, a depth-over-time history
(the edge's depth, else the dense map's median) and the check's verdict with its last lines for the page to
poll."""
from __future__ import annotations

import collections
import threading
import time

import numpy as np

from psvs.health.rolling import RollingCheck
from psvs.live.dense import DenseFrame, DenseSensor
from psvs.live.drift_gate import drifted, withheld
from psvs.live.tracker import EdgeTracker, TrackStep
from psvs.web.runner import BackgroundRunner
from psvs.web.sources import Source

#: Serialises the dense computations of the page's requests and of the live loop: Numba's parallel kernels
#: may not run from two threads at once under its fallback threading layer (workqueue).
DENSE_LOCK = threading.Lock()

HISTORY = 600          # depth samples kept for the plot
SHOWN_PAIRS = 400      # pixel pairs sent to the page per frame (evenly subsampled)
HEALTH_LINES = 5       # the self-check's last lines (a verdict crossing the tolerance) kept for the page


class LiveRunner(BackgroundRunner):
    """Start with a source and a tracker; poll :meth:`state` and :meth:`frame`; stop with :meth:`stop`."""

    def __init__(self):
        super().__init__()
        self._reset()

    def _reset(self):
        self._frame = None
        self._step: TrackStep | None = None
        self._dense: DenseFrame | None = None
        self._history = collections.deque(maxlen=HISTORY)
        self._health: RollingCheck | None = None
        self._health_lines = collections.deque(maxlen=HEALTH_LINES)
        self._times = collections.deque(maxlen=30)
        self._error = ""
        self._t0 = time.perf_counter()

    def start(self, source: Source, tracker: EdgeTracker | None, dense: DenseSensor | None = None,
              health: RollingCheck | None = None) -> None:
        """Stop any running loop and start a new one (one loop at a time, even with concurrent requests),
        with an edge tracker, a dense sensor, or both, and the rolling self-check unless ``health`` is None."""
        if tracker is None and dense is None:
            raise ValueError("live mode needs an edge to track or dense depth")
        def prepare():
            frames = source.frames()
            with self._lock:
                self._reset()
                self._health = health
            return frames, tracker, dense, health, source.fps
        self._start_loop(prepare, self._loop, "psvs-live")

    def _loop(self, frames, tracker: EdgeTracker | None, dense: DenseSensor | None, health: RollingCheck | None,
              fps: float) -> None:
        period = 1.0 / fps if fps > 0 else 0.0
        next_t = time.perf_counter()
        for k, frame in enumerate(frames):
            if self._stop.is_set():
                break
            t0 = time.perf_counter()
            step = tracker.step(frame) if tracker is not None else None
            dstep = None
            if dense is not None:
                with DENSE_LOCK:
                    dstep = dense.step(frame)
            event = None if health is None else health.step(frame, k, time.perf_counter() - t0)   # OpenCV only
            if health is not None and drifted(health.latest):     # no depth through a moved calibration
                step, dstep = withheld(step, dstep)
            now = time.perf_counter()
            with self._lock:
                self._frame, self._step, self._dense = frame, step, dstep
                if event is not None:
                    self._health_lines.append(event.line)
                self._times.append(now)
                self._history.append((now - self._t0, step.depth_mm if step is not None else dstep.median_z_mm))
            if period:   # play files and simulations at their nominal rate
                next_t = max(next_t + period, now - period)
                self._stop.wait(max(0.0, next_t - time.perf_counter()))

    def dense(self) -> DenseFrame | None:
        """The latest dense frame of the live run (None before the first)."""
        with self._lock:
            return self._dense

    def state(self) -> dict:
        """The live run's state for the page: the last step's result, the depth history, the frame rate, the
        error that stopped it."""
        with self._lock:
            step, dstep, times = self._step, self._dense, list(self._times)
            history = [[round(t, 3), None if not np.isfinite(z) else round(z, 3)] for t, z in self._history]
            error = self._error
            health = None if self._health is None else {**self._health.summary(), "lines": list(self._health_lines)}
        fps = (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 and times[-1] > times[0] else 0.0
        out = {"running": self.running, "error": error, "fps": round(fps, 2), "history": history, "health": health}
        if step is not None:
            out.update(frame=step.frame, tracked=step.ok, message=step.message,
                       latency_ms=round(step.elapsed_s * 1e3, 3),
                       depth_mm=step.depth_mm if step.ok else None,
                       disparity_px=step.disparity_px if step.ok else None,
                       seed_px=list(step.seed_px) if step.seed_px else None)
            if step.ok:
                k = np.unique(np.linspace(0, len(step.pair) - 1, min(SHOWN_PAIRS, len(step.pair))).astype(int))
                out["left_px"] = np.round(step.pair.left_px[k], 2).tolist()
                out["right_px"] = np.round(step.pair.right_px[k], 2).tolist()
        if dstep is not None:
            if step is None:
                out.update(frame=dstep.frame, latency_ms=round(dstep.elapsed_s * 1e3, 3))
            out["dense"] = {"frame": dstep.frame, "median_z_mm": dstep.median_z_mm if np.isfinite(dstep.median_z_mm)
                            else None, "answered_pct": round(dstep.answered_pct, 2),
                            "supported": bool(dstep.supported), "mapped": bool(dstep.mapped),
                            "refusal": dstep.refusal,
                            "latency_ms": round(dstep.elapsed_s * 1e3, 3), "range_px": list(dstep.searched_px)}
        return out
