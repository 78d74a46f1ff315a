"""Only psvs's own words on the terminal: what the libraries under a command print on their own is kept off.

OpenCV logs to stderr ("[ WARN:0@0.4] global cap_v4l.cpp:914 open VIDEOIO(V4L2:/dev/video99): can't open
camera by index") before psvs can say the same in one line; numpy warns of every overflow and NaN an
arithmetic step meets ("RuntimeWarning: invalid value encountered in multiply", two lines with the source
line), which psvs's own checks then answer in the user's terms; other libraries warn or log of their
internals. :func:`quiet_libraries` silences these for a command's run and prints the warnings psvs itself
raises (``warnings.warn`` in psvs's code, e.g. "complex image is constant") as one line each,
``psvs CMD: warning: ...``. What C libraries print while decoding a file is caught where the file is read
(:mod:`psvs.io.cstderr`). Outside psvs.cli, so that a command loads no other command's module.
"""
from __future__ import annotations

import contextlib
import logging
import os
import re
import sys
import warnings

#: numpy's floating-point warnings (from its ufuncs' error state): silenced like ``np.errstate(all="ignore")``
#: for threads, which do not inherit the error state of the thread that started them.
FLOATING_POINT = r"(divide by zero|overflow|underflow|invalid value) encountered"
# the modules whose frames hold warnings' own machinery, between warnings.warn's caller and showwarning
_WARNINGS_MODULES = ("warnings", "_py_warnings")


@contextlib.contextmanager
def quiet_libraries(name: str):
    """For the block: OpenCV's log off, numpy's floating-point warnings off, Python logging without its
    last-resort printer, and a warning printed only when psvs's own code raised it, as
    ``<name>: warning: <message>``; everything restored afterwards."""
    import numpy as np
    root = logging.getLogger()
    null = logging.NullHandler()        # a handler anywhere stops logging's last resort printing to stderr
    with warnings.catch_warnings(), np.errstate(all="ignore"), _opencv_silent():
        warnings.filterwarnings("ignore", message=FLOATING_POINT, category=RuntimeWarning)
        warnings.showwarning = lambda message, *_, **__: _show(name, message, sys._getframe(1))
        root.addHandler(null)
        try:
            yield
        finally:
            root.removeHandler(null)


def _show(name: str, message, frame) -> None:
    """Print a warning as one line when psvs raised it (``frame``: the frame that asked to show it)."""
    if raised_by_psvs(frame):
        text = str(message).strip()
        print(f"{name}: warning: {text.splitlines()[0] if text else type(message).__name__}", file=sys.stderr)


def raised_by_psvs(frame) -> bool:
    """Whether the warning being shown was raised by psvs's code: the first frame from ``frame`` outwards
    that is not the warnings module's (the caller of ``warnings.warn``) is a psvs module's. A warning raised
    inside a library called by psvs is the library's, whatever its ``stacklevel`` names as its origin."""
    while frame is not None and frame.f_globals.get("__name__") in _WARNINGS_MODULES:
        frame = frame.f_back
    module = frame.f_globals.get("__name__", "") if frame is not None else ""
    return re.match(r"psvs(\.|$)", module) is not None


@contextlib.contextmanager
def _opencv_silent():
    """OpenCV's log level SILENT: set on a loaded cv2, or by OPENCV_LOG_LEVEL for one loaded in the block
    (OpenCV reads it once); FFmpeg's under OpenCV quiet too (OPENCV_FFMPEG_LOGLEVEL, read when OpenCV first
    opens a video). A level the user chose with either variable stands."""
    with _environ("OPENCV_FFMPEG_LOGLEVEL", "-8"):          # AV_LOG_QUIET
        if "OPENCV_LOG_LEVEL" in os.environ:
            yield
            return
        cv2 = sys.modules.get("cv2")
        log = getattr(getattr(cv2, "utils", None), "logging", None)
        if log is None:
            with _environ("OPENCV_LOG_LEVEL", "SILENT"):
                yield
            return
        level = log.getLogLevel()
        log.setLogLevel(log.LOG_LEVEL_SILENT)
        try:
            yield
        finally:
            log.setLogLevel(level)


@contextlib.contextmanager
def _environ(name: str, value: str):
    """The environment variable ``name`` set to ``value`` for the block, unless it is set already."""
    if name in os.environ:
        yield
        return
    os.environ[name] = value
    try:
        yield
    finally:
        os.environ.pop(name, None)
