"""What the web page's one-shot background jobs (the calibration, the simulated tracking run) share: one job at a
time in a daemon thread, its state a dict the page polls, an exception said on the page in one line."""
from __future__ import annotations

import threading

#: Longest error line a job keeps for the page (characters).
MAX_ERROR = 300


class OneJob:
    """One job at a time; :meth:`state` for the page: ``running``, ``error`` ('' none) and the job's own keys
    (``idle``: their values before a job starts)."""

    def __init__(self, busy: str, **idle):
        self._busy, self._idle = busy, idle
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._state = {"running": False, "error": "", **idle}

    @property
    def running(self) -> bool:
        """Whether a job is under way."""
        return self._thread is not None and self._thread.is_alive()

    def _start(self, name: str, work, **state) -> None:
        """Run ``work()`` in a new thread called ``name``, the state reset to ``idle`` updated with ``state``;
        ValueError (the ``busy`` line) while a job runs."""
        with self._lock:
            if self.running:
                raise ValueError(self._busy)
            self._state = {"running": True, "error": "", **self._idle, **state}
            self._thread = threading.Thread(target=self._guarded, args=(work,), daemon=True, name=name)
            self._thread.start()

    def _guarded(self, work) -> None:
        try:
            work()
        except Exception as exc:              # noqa: BLE001  - said on the page, in one line
            text = str(exc).strip()
            self._update(error=(text.splitlines()[-1] if text else type(exc).__name__)[:MAX_ERROR])
        finally:
            self._update(running=False)

    def _update(self, **state) -> None:
        """Set some of the state's keys (under the lock the page's reads take)."""
        with self._lock:
            self._state.update(state)

    def state(self) -> dict:
        """A copy of the job's state."""
        with self._lock:
            return dict(self._state)
