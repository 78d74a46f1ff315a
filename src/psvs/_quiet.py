"""Only psvs's own words on the terminal: what the libraries under a command print on their own is kept off.

OpenCV logs to stderr ("[ WARN:0@0.4] global cap_v4l.cpp:914 open VIDEOIO(V4L2:/dev/video99): can't open
camera by index") before psvs can say the same in one line; numpy warns of every overflow and NaN an
arithmetic step meets ("RuntimeWarning: invalid value encountered in multiply", two lines with the source
line), which psvs's own checks then answer in the user's terms; other libraries warn or log of their
internals. :func:`quiet_libraries` silences these for a command's run and prints the warnings psvs itself
raises (``warnings.warn`` in psvs's code, e.g. "complex image is constant") as one line each,
``psvs CMD: warning: ...``. Outside psvs.cli, so that a command loads no other command's module.

What C libraries print on the process's standard error is caught where the file is read: OpenCV's image
decoders run libpng, libjpeg and libtiff, which write their complaints straight to file descriptor 2
("libpng error: Read Error"), where Python's ``sys.stderr`` cannot intercept them. A reader wraps its decode
in :func:`c_stderr_captured`, so those lines never reach the terminal, and turns what was caught into its
own one-line error when the decode failed (:func:`library_reason`).
"""
from __future__ import annotations

import contextlib
import io
import logging
import os
import re
import sys
import tempfile
import threading
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
    (OpenCV reads it once). FFmpeg's log is left as OpenCV sets it (errors, on standard error): they are how a
    decoder says a frame is damaged, and psvs catches them around each open and read of a video
    (:func:`psvs.io.video.decoded`); OPENCV_FFMPEG_LOGLEVEL would send them to standard output instead. A
    level the user chose with OPENCV_LOG_LEVEL stands."""
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

#: Longest library message quoted in an error (characters).
MAX_REASON = 200
#: Most bytes of caught output kept (a decoder that loops on warnings cannot fill memory).
MAX_CAUGHT = 64 * 1024

# File descriptor 2 is one per process: two threads redirecting it at once would restore each other's
# redirection. Re-entrant, so a nested capture in one thread restores in order.
_LOCK = threading.RLock()


@contextlib.contextmanager
def c_stderr_captured():
    """Redirect file descriptor 2 to a temporary file for the block; yields a list that holds, after the
    block, the non-empty lines written there (stripped).

    Anything written to the process's standard error during the block is caught, whoever writes it, so the
    block should hold only the library call; a program that captures on a thread while another prints holds
    :func:`python_stderr_aside` meanwhile. When descriptor 2 cannot be duplicated (closed), the block runs
    without capture and the list stays empty."""
    lines: list[str] = []
    with _LOCK:
        _flush_python_stderr()
        try:
            saved = os.dup(2)
        except OSError:
            yield lines
            return
        try:
            with tempfile.TemporaryFile() as tmp:
                os.dup2(tmp.fileno(), 2)
                try:
                    yield lines
                finally:
                    _flush_python_stderr()
                    os.dup2(saved, 2)
                    tmp.seek(0)
                    text = tmp.read(MAX_CAUGHT).decode("utf-8", "replace")
                    lines.extend(s.strip() for s in text.splitlines() if s.strip())
        finally:
            os.close(saved)


#: Text streams on copies of descriptor 2, by its file's (device, inode), kept open (:func:`python_stderr_aside`).
_ASIDE: dict = {}
#: [holders of python_stderr_aside, the sys.stderr it replaced, the stream it put there]
_HELD: list = [0, None, None]


@contextlib.contextmanager
def python_stderr_aside():
    """For the block (nested and from several threads alike): Python's ``sys.stderr``, when it writes to
    descriptor 2, points at a copy of that descriptor, so that what Python prints reaches the terminal while
    another thread's :func:`c_stderr_captured` has descriptor 2 redirected (a live run's lines while its next
    frame decodes on a thread, :class:`psvs.live.source.VideoSource`). Swapped while no capture is running,
    so no line is printed half on either side."""
    with _LOCK:
        if _HELD[0] == 0:
            aside = _aside(sys.stderr)
            if aside is not None:
                _flush_python_stderr()
                _HELD[1:] = [sys.stderr, aside]
                sys.stderr = aside
        _HELD[0] += 1
    try:
        yield
    finally:
        with _LOCK:
            _HELD[0] -= 1
            if _HELD[0] == 0 and _HELD[2] is not None:
                if sys.stderr is _HELD[2]:
                    _HELD[2].flush()
                    sys.stderr = _HELD[1]
                _HELD[1:] = [None, None]


def _aside(stream):
    """A line-buffered text stream on a copy of descriptor 2 as it is now (kept in :data:`_ASIDE`), when
    ``stream`` writes to descriptor 2; else None (a stream of pytest's, or a file of the caller's: the
    redirection misses it)."""
    try:
        if stream is None or stream.fileno() != 2:
            return None
        st = os.fstat(2)
    except (AttributeError, OSError, ValueError):
        return None
    key = (st.st_dev, st.st_ino)
    if key not in _ASIDE:
        _ASIDE[key] = io.TextIOWrapper(io.FileIO(os.dup(2), "w"), encoding=getattr(stream, "encoding", None),
                                       errors=getattr(stream, "errors", None), line_buffering=True,
                                       write_through=True)
    return _ASIDE[key]


def _flush_python_stderr() -> None:
    """Flush Python's buffered stderr, so its text lands on the side of the redirection it was written on."""
    with contextlib.suppress(AttributeError, OSError, ValueError):
        sys.stderr.flush()


def library_reason(lines: list[str]) -> str:
    """The first of a library's messages (what it printed, or its exception's text) as short plain words:
    OpenCV's "[ERROR:0@0.1] global loadsave.cpp:1409 ...: error: (-2:Unspecified error) Unexpected end of
    input stream in function 'readBlock'" becomes "Unexpected end of input stream", FFmpeg's
    "[mov,mp4,m4a @ 0x55fe10] moov atom not found" "moov atom not found"; libpng's lines stay as they are
    ("libpng error: Read Error"). Empty when there is none."""
    for line in (s.strip() for text in lines for s in text.splitlines()):
        m = re.search(r"error: \(-?\d+:([^)]*)\)\s*(.*?)\s*(?:in function '.*)?$", line)
        line = (m.group(2) or m.group(1)) if m else re.sub(r"^\[[^]]*\]\s*(global \S+ )?", "", line)
        if line:
            return line[:MAX_REASON]
    return ""
