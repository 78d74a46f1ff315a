"""What the web UI's background loops (live mode, the capture assistant) share: one loop thread at a time,
started and stopped under a lock even with concurrent requests, its latest state guarded by another."""
from __future__ import annotations

import threading


class BackgroundRunner:
    """A loop thread: :meth:`_start_loop` stops any running one and starts a new one; :meth:`stop` ends it.
    Subclasses hold ``self._lock`` while they read or write the state the page polls."""

    #: How long a stop waits for the loop to end (its current frame's work), s.
    STOP_TIMEOUT_S = 5.0

    def __init__(self):
        self._frame = None                     # the latest frame the loop read (H, W) uint8
        self._error = ""                       # what stopped the loop, for the page
        self._lock = threading.Lock()          # guards the loop's latest state
        self._control = threading.Lock()       # serialises start and stop
        self._thread: threading.Thread | None = None
        self._lingering: threading.Thread | None = None   # a stopped loop's thread still in its last step
        self._stop = threading.Event()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def _start_loop(self, prepare, target, name: str) -> None:
        """Under the control lock: stop the running loop, call ``prepare()`` (its return value is the args of
        ``target``, the first a frame iterator), then run ``target(*args)`` in a new daemon thread
        (:meth:`_guarded`)."""
        with self._control:
            self._stop_locked()
            args = prepare()
            self._stop.clear()
            self._thread = threading.Thread(target=self._guarded, args=(target, *args), daemon=True, name=name)
            self._thread.start()

    def _guarded(self, target, frames, *args) -> None:
        """``target(frames, *args)``: an exception it raises is kept for the page (the server keeps running);
        the frames are closed either way."""
        try:
            target(frames, *args)
        except Exception as exc:
            with self._lock:
                self._error = f"{type(exc).__name__}: {exc}"
        finally:
            close_frames(frames)

    def frame(self):
        """The latest frame the loop read, (H, W) uint8, or None."""
        with self._lock:
            return self._frame

    def stop(self) -> None:
        """Stop the background run (stopping a stopped run does nothing)."""
        with self._control:
            self._stop_locked()

    def _stop_locked(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=self.STOP_TIMEOUT_S)
            if self._thread.is_alive():       # still in a long step: it ends after it, reading nothing more
                self._lingering = self._thread
        self._thread = None

    @property
    def finishing(self) -> bool:
        """Whether a stopped loop's thread is still finishing its last step (it may still hold its source: a
        camera opened by it is not released yet)."""
        return self._lingering is not None and self._lingering.is_alive()


def close_frames(frames) -> None:
    """Close a frame iterator (a generator releases its camera or file)."""
    close = getattr(frames, "close", None)
    if close:
        close()
