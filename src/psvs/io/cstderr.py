"""What C libraries print on the process's standard error, caught instead of shown.

OpenCV's image decoders run libpng, libjpeg and libtiff, which write their complaints straight to file
descriptor 2 ("libpng error: Read Error"), where Python's ``sys.stderr`` cannot intercept them. A reader
wraps its decode in :func:`c_stderr_captured`, so those lines never reach the terminal, and turns what was
caught into its own one-line error when the decode failed.
"""
from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import threading

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
    block should hold only the library call. When descriptor 2 cannot be duplicated (closed), the block runs
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
