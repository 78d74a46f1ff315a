"""The web UI's capture assistant: a background thread that reads the source's frames through a
:class:`~psvs.calibrate.capture.CaptureAssistant`, saves each good view into the capture folder, and keeps
the latest frame, step and events for the page to poll (the same words ``psvs capture`` prints)."""
from __future__ import annotations

import collections
import time
from dataclasses import dataclass

import numpy as np

from psvs.calibrate.capture import (
    CaptureAssistant,
    CaptureFolder,
    CaptureParams,
    CaptureStep,
    check_card_visible,
    event_lines,
)
from psvs.optics.rig import Rig
from psvs.targets.detect import Target
from psvs.web.runner import BackgroundRunner
from psvs.web.sources import Source

EVENTS = 200            # event lines kept for the page


@dataclass(frozen=True, eq=False)
class CaptureSetup:
    """The capture's card, its file's bytes (copied as the folder's target.toml) and the folder: from ``psvs
    serve --target T --capture-to DIR``, or chosen in the page (``POST /api/capture/setup``)."""

    target: Target
    target_text: bytes
    folder: str


def describe_target(t) -> str:
    """The card in a few words, as the page shows it (a circle grid, asymmetric or not, or a ChArUco board)."""
    if hasattr(t, "squares_x"):
        return (f"ChArUco {t.squares_x}x{t.squares_y} squares of {t.square_mm:g} mm, markers {t.marker_mm:g} mm "
                f"({t.dictionary})")
    kind = "asymmetric grid of " if type(t).__name__.startswith("Asymmetric") else ""
    return f"{kind}{t.rows}x{t.cols} discs, {t.diameter_mm:g} mm across, {t.spacing_mm:g} mm apart"


class CaptureRunner(BackgroundRunner):
    """Start with a source, a rig and params; poll :meth:`state` and :meth:`frame`; stop with :meth:`stop`.
    A second start in one app resumes the same set (its coverage, its folder) with the new params' count."""

    def __init__(self, setup: CaptureSetup | None):
        super().__init__()
        self.setup = setup
        self._assistant: CaptureAssistant | None = None
        self._folder: CaptureFolder | None = None
        self._frame, self._step, self._error, self._progress = None, None, "", None
        self._events: collections.deque = collections.deque(maxlen=EVENTS)

    #: The capture loop's frame may take longer (detecting the card in both views of a large frame).
    STOP_TIMEOUT_S = 10.0

    def configure(self, setup: CaptureSetup) -> None:
        """Take a new card and folder (chosen in the page); a new set starts. Refused while capturing."""
        with self._control:                  # not while a start or stop runs
            if self.running:
                raise ValueError("stop the capture before choosing another card or folder")
            with self._lock:
                self.setup, self._assistant, self._folder = setup, None, None
                self._frame, self._step, self._error, self._progress = None, None, "", None
                self._events.clear()

    def start(self, source: Source, rig: Rig, params: CaptureParams) -> None:
        """Check the card against the rig and the range, then watch the source (ValueError, one line, else)."""
        if self.setup is None:
            raise ValueError("capture needs a card and a folder: choose them (the card's target.toml and a new "
                             "folder) first")
        check_card_visible(rig, self.setup.target, params)

        def prepare():
            frames = source.frames()
            with self._lock:
                if self._folder is None:
                    self._folder = CaptureFolder(self.setup.folder, self.setup.target_text)
                old = self._assistant
                self._assistant = CaptureAssistant(self.setup.target, rig, params)
                if old is not None:          # resume: what was saved stays saved and covered
                    self._assistant.covered, self._assistant.saved = old.covered, old.saved
                self._progress = _progress(self._assistant, self._folder)
                self._error = ""
            return frames, source.fps
        self._start_loop(prepare, self._loop, "psvs-capture")

    def _loop(self, frames, fps: float) -> None:
        assistant, folder = self._assistant, self._folder
        t0 = time.monotonic()
        for k, frame in enumerate(frames):
            if self._stop.is_set():
                break
            step = assistant.step(frame, k / fps if fps > 0 else time.monotonic() - t0)
            name = folder.save(frame) if step.status == "saved" else None
            with self._lock:
                self._frame, self._step = frame, step
                self._progress = _progress(assistant, folder)
                self._events.extend(event_lines(step, name, assistant.params.views))
                if step.complete:
                    self._events.append(f"enough to calibrate: {step.saved} views in {folder.folder}")
            if step.complete:
                break

    def state(self) -> dict:
        """The set's progress: views saved and asked for, what each bin holds, what is missing, the latest
        step's status and hint, the event lines, the saved files."""
        with self._lock:        # the progress and the events of one frame, together
            step, progress = self._step, self._progress
            out = {"available": self.setup is not None, "running": self.running, "error": self._error,
                   "events": list(self._events), "folder": self.setup.folder if self.setup else None}
        if progress is not None:
            out.update(progress)
        if step is not None:
            out.update(_step_fields(step))
        return out


def _progress(a: CaptureAssistant, folder: CaptureFolder) -> dict:
    """The set's progress after a frame (copied: the loop goes on changing the assistant)."""
    return {"views": a.params.views, "saved": len(a.saved), "complete": a.complete, "covered": dict(a.covered),
            "missing": a.describe_missing(), "names": list(folder.names)}


def _step_fields(step: CaptureStep) -> dict:
    pose = step.pose
    return {"frame": step.frame, "status": step.status, "hint": step.hint, "reason": step.reason,
            "distance_mm": round(pose.distance_mm, 1) if pose else None,
            "speed_px_s": round(step.speed_px_s, 1) if np.isfinite(step.speed_px_s) else None,
            "bins": sorted(step.bins)}
