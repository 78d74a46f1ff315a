"""What one ``psvs serve`` app remembers between requests: its source and rig, the current still image and its
name, the last match result and the live-mode runner.

One :class:`Session` belongs to one app (``app.state.session``); routes receive it through FastAPI's dependency
injection (:data:`SessionDep`), so two apps in one process never share an image or a result. The still image,
its name and the last result change together (an upload replaces the image and forgets the result), so they are
read and written under one lock.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Annotated, NamedTuple

import numpy as np
from fastapi import Depends, Request

from psvs.match.correspondence import MatchResult
from psvs.optics.rig import Rig
from psvs.web.calibration_job import CalibrationJob
from psvs.web.capture_runner import CaptureRunner
from psvs.web.live_runner import LiveRunner
from psvs.web.sources import Source
from psvs.web.track_job import TrackJob


class Still(NamedTuple):
    """The current still image as one request sees it.

    Attributes
    ----------
    grey : ndarray
        (H, W) uint8 complex image. It is never written in place: an upload replaces it by a new array.
    name : str
        What the page shows for it (the source's name, or "uploaded image").
    generation : int
        Counts the images this session has had; a result computed on this image is kept only while it is
        still the current one (:meth:`Session.keep_result`).
    """

    grey: np.ndarray
    name: str
    generation: int


@dataclass(eq=False)
class Session:
    """One app's state: one user, on their own machine.

    Parameters
    ----------
    source : Source
        What the app shows; its still image is the first current image and its frames feed live mode.
    rig : Rig
        The rig every computation uses.
    rig_name : str
        Shown with the rig's f, b and plate thickness (e.g. the calibrated rig file).
    capture : CaptureRunner
        The capture assistant (its card and folder, when the app has them).
    calibration : CalibrationJob
        The page's calibration of a folder of card views.
    tracking : TrackJob
        The page's simulated seam-tracking run.
    """

    source: Source
    rig: Rig
    rig_name: str = "default rig"
    live: LiveRunner = field(default_factory=LiveRunner)
    capture: CaptureRunner = field(default_factory=lambda: CaptureRunner(None))
    calibration: CalibrationJob = field(default_factory=CalibrationJob)
    tracking: TrackJob = field(default_factory=TrackJob)
    _lock: threading.Lock = field(default_factory=threading.Lock, init=False, repr=False)
    #: held while the source is replaced or a reader of it (live mode, the capture) starts: a reader started
    #: meanwhile reads the new source, never the old one
    _source_lock: threading.Lock = field(default_factory=threading.Lock, init=False, repr=False)
    _still: np.ndarray = field(init=False, repr=False)
    _name: str = field(init=False)
    _generation: int = field(default=0, init=False)
    _result: MatchResult | None = field(default=None, init=False, repr=False)
    _dense_maps: dict | None = field(default=None, init=False, repr=False)
    _dense_runs: int = field(default=0, init=False)
    _mount: dict | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        w, h = self.image_size_px
        if self.source.still.shape != (h, w):
            raise ValueError(f"{self.source.name} is {self.source.still.shape[1]}x{self.source.still.shape[0]} px "
                             f"but the rig's camera is {w}x{h} px")
        self._still, self._name = self.source.still, self.source.name

    @property
    def image_size_px(self) -> tuple[int, int]:
        """(W, H) of the rig's camera: every image the session holds has this size."""
        w, h = self.rig.camera.image_size_px
        return int(w), int(h)

    def replace_rig(self, rig: Rig, name: str) -> None:
        """Make ``rig`` the one every computation uses (chosen in the page). Its camera must have the served
        image's size (ValueError, one line, else); live mode and the capture stop (they ran through the old
        rig) and the last match result is forgotten."""
        w, h = self.image_size_px
        rw, rh = (int(x) for x in rig.camera.image_size_px)
        if (rw, rh) != (w, h):
            raise ValueError(f"{name}'s camera is {rw}x{rh} px, the served images {w}x{h} px: serve a camera, video "
                             "or image of that size with it (psvs serve --rig)")
        with self._source_lock:           # no reader starts meanwhile through the old rig
            self.live.stop()
            self.capture.stop()
            with self._lock:
                self.rig, self.rig_name, self._result, self._dense_maps = rig, name, None, None
                self._mount = None        # made for the old rig
                self._generation += 1     # a match still running through the old rig stores nothing

    def replace_source(self, source: Source) -> None:
        """Serve ``source`` from now on (a video chosen in the page): its frames must be the rig's camera's size
        (ValueError, one line, else); live mode and the capture stop (they read the old source), its first
        frame becomes the current image and the last result is forgotten. A source of the wrong size is refused
        before anything stops."""
        self._check_size(source)
        self.open_source(lambda: source)

    def open_source(self, make) -> Source:
        """Serve the source ``make()`` opens (a camera chosen in the page), made while no reader holds the
        current one (live mode and the capture stop first, and are not restarted: a camera serves one program
        at a time), then as :meth:`replace_source`; the source served before stays (live mode stopped) when
        ``make`` fails, its frames are not the rig's camera's size, or a stopped loop is still finishing a long
        step with the old source (ValueError, one line)."""
        with self._source_lock:
            self.live.stop()
            self.capture.stop()
            if self.live.finishing or self.capture.finishing:
                raise ValueError("live mode or the capture is still finishing a frame of the source served now "
                                 "(it holds it until then): try again in a moment")
            source = make()
            self._check_size(source)
            self.source = source
            self.replace_still(source.still, source.name)
        return source

    def _check_size(self, source: Source) -> None:
        w, h = self.image_size_px
        if source.still.shape != (h, w):
            raise ValueError(f"{source.name}'s frames are {source.still.shape[1]}x{source.still.shape[0]} px, "
                             f"the rig's camera {w}x{h} px: a video of that camera, or the rig of this one")

    def start_live(self, tracker, dense, health) -> None:
        """Start live mode on the current source (:meth:`LiveRunner.start`'s arguments); the capture stops
        (one reader of the source at a time)."""
        with self._source_lock:
            self.capture.stop()
            self.live.start(self.source, tracker, dense, health)

    def start_capture(self, params) -> None:
        """Start (or resume) the capture on the current source through the rig; live mode stops (one reader
        of the source at a time)."""
        with self._source_lock:
            self.live.stop()
            self.capture.start(self.source, self.rig, params)

    def still(self) -> Still:
        """The current image, its name and generation, read together under the lock."""
        with self._lock:
            return Still(self._still, self._name, self._generation)

    def replace_still(self, grey: np.ndarray, name: str) -> None:
        """Make ``grey`` (H, W) uint8 the current image and forget the last result (it was of the old image)."""
        w, h = self.image_size_px
        if grey.shape != (h, w) or grey.dtype != np.uint8:
            raise ValueError(f"{name} must be a {w}x{h} uint8 grey image, got {grey.dtype} {grey.shape}")
        with self._lock:
            self._still, self._name, self._result, self._dense_maps = grey, name, None, None
            self._generation += 1

    def keep_result(self, result: MatchResult, generation: int) -> bool:
        """Remember ``result`` for the exports if it was computed on the current image (``generation`` from
        :meth:`still`); a result of an image replaced meanwhile is not kept. Returns whether it was kept."""
        with self._lock:
            if generation != self._generation:
                return False
            self._result = result
            return True

    def keep_dense_maps(self, maps: dict, generation: int) -> int | None:
        """Remember the last dense run's full-resolution maps (name -> float32 (H', W')) of the current image
        (``generation`` from :meth:`still`; a run of an image replaced meanwhile is not kept). Returns the run's
        own number (each kept run a new one: two runs on one image are told apart), or None."""
        with self._lock:
            if generation != self._generation:
                return None
            self._dense_runs += 1
            self._dense_maps = {"run": self._dense_runs, **maps}
            return self._dense_runs

    def dense_maps(self) -> dict | None:
        """The last dense run's maps of the current image and rig (``run`` and each map), or None."""
        with self._lock:
            return self._dense_maps

    def keep_mount(self, files: dict, rig: Rig) -> bool:
        """Remember the files of a mount made in the page ({name: bytes}) for their downloads, if ``rig`` (the
        rig it was made for) is still the served one. Returns whether they were kept."""
        with self._lock:
            if rig is not self.rig:
                return False
            self._mount = dict(files)
            return True

    def mount_file(self, name: str) -> bytes | None:
        """One file of the mount made in the page for the served rig, or None (none made, or not that name)."""
        with self._lock:
            return None if self._mount is None else self._mount.get(name)

    def result(self) -> MatchResult | None:
        """The last match result of the current image, or None."""
        with self._lock:
            return self._result


def get_session(request: Request) -> Session:
    """FastAPI dependency: the session of the app that received ``request``."""
    return request.app.state.session


#: A route parameter annotated with this receives its app's :class:`Session`.
SessionDep = Annotated[Session, Depends(get_session)]
