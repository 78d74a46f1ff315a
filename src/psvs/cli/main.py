"""``psvs`` entry point: one subcommand per module; a result, or one line on stderr and a non-zero status
(bad input 2, a measurement the data cannot give 1, anything unexpected 1 as an "internal error") -- never
a traceback, unless PSVS_DEBUG=1 asks for it.

A command's module is psvs.cli.<command>_cmd (dashes as underscores). ``psvs COMMAND ...`` imports only that
command's module, so a command starts without loading every other command's libraries (``psvs track``
must reach its first control cycle within 2 s); ``psvs --help`` and an unknown command load them all.
"""
from __future__ import annotations

import argparse
import atexit
import contextlib
import importlib
import io
import os
import re
import signal
import sys
import threading
from typing import NoReturn

from psvs._budget import small_pages
from psvs._quiet import quiet_libraries
from psvs.errors import MeasurementError, RigGeometryError

COMMANDS = ("demo", "rig", "design", "triangulate", "fit-refraction", "simulate", "match", "measure", "calibrate",
            "card-views", "sweep-views", "capture", "table1", "disparity", "dense-eval", "serve", "live", "handeye",
            "track", "replay", "export-calibration", "cameras", "adjust", "mount", "batch", "montecarlo", "examples",
            "check", "refit")


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's usage errors: one line, exit 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``psvs`` parser with every command, or with the command ``only`` alone."""
    parser = _Parser(prog="psvs", description="Pseudo Stereo Vision System toolkit (Pachidis & Lygouras).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser, required=True)
    for name in COMMANDS if only is None else (only,):
        importlib.import_module(f"psvs.cli.{name.replace('-', '_')}_cmd").add_parser(sub)
    return parser


#: Set (to anything but 0) to let an internal error end in Python's traceback, and to leave OpenCV's log,
#: numpy's floating-point warnings and other libraries' warnings as the libraries print them.
DEBUG_ENV = "PSVS_DEBUG"


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (a service manager stopping psvs, a closed terminal) raised as an interrupt, so that
    it unwinds as Ctrl-C does: every write in progress removes its temporary file (psvs.io.atomic), and the
    exit status is 128 + the signal's number."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _terminated(signum, frame):
    raise Terminated(signum)


@contextlib.contextmanager
def _signals_unwind():
    """SIGTERM and SIGHUP raise :class:`Terminated` while a command runs (main thread only; the handlers
    before are restored after, so a program that calls :func:`main` keeps its own)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, _terminated) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


#: A value that is a comma-separated list of numbers starting with a negative one (``-150,0,0``).
_NEGATIVE_LIST = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(,[-+]?(\d+\.?\d*|\.\d+)?([eE][-+]?\d+)?)+$")


def negative_lists_joined(argv: list[str]) -> list[str]:
    """``argv`` with each ``--option -1,2,3`` written ``--option=-1,2,3``: argparse takes a value that starts
    with "-" for an option unless it is one plain negative number, and said "expected one argument" of
    ``--move-mm -150,0,0`` (trial 44), an ordinary request to move the rig along -x."""
    out = []
    for word in argv:
        if out and out[-1].startswith("--") and "=" not in out[-1] and _NEGATIVE_LIST.match(word):
            out[-1] = f"{out[-1]}={word}"
        else:
            out.append(word)
    return out


def main(argv: list[str] | None = None) -> int:
    """Run ``psvs COMMAND ...``: a result and exit status 0, or one line on stderr and a non-zero status.

    Bad input (ValueError, TypeError, OSError, RigGeometryError) exits 2, a measurement the data cannot give
    (MeasurementError) 1 with "cannot measure: ...", Ctrl-C 130, and any other exception -- a fault of psvs
    or of a library under it -- 1 with "internal error: <its type>: <its message>", never a traceback unless
    :data:`DEBUG_ENV` is set. While the command runs, what libraries print on their own is kept off the
    terminal (:func:`quiet_libraries`)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    small_pages()
    command = argv[0] if argv and argv[0] in COMMANDS else None
    debug = os.environ.get(DEBUG_ENV, "").strip() not in ("", "0")
    name = f"psvs {command}" if command else "psvs"
    try:    # a signal while the command's contexts close (its result already out) ends as one during it
        with contextlib.ExitStack() as stack:
            stack.enter_context(_signals_unwind())
            try:    # the command's module (and its libraries) load here: Ctrl-C then ends as it does later on
                if not debug:
                    stack.enter_context(quiet_libraries(name))
                args = build_parser(command).parse_args(negative_lists_joined(argv))
            except KeyboardInterrupt as exc:
                return _interrupted("psvs", exc)
            except Exception as exc:        # a library that does not load
                if debug:
                    raise
                return _internal_error(name, exc)
            return _run(args, debug)
    except KeyboardInterrupt as exc:
        return _interrupted(name, exc)


def _interrupted(name: str, exc: KeyboardInterrupt) -> int:
    if isinstance(exc, Terminated):
        print(f"{name}: terminated ({signal.Signals(exc.signum).name})", file=sys.stderr)   # no ^C echo to end
        return 128 + exc.signum
    print(f"\n{name}: interrupted", file=sys.stderr)
    return 130


def _run(args, debug: bool) -> int:
    """Run the parsed command; its exceptions become the exit status and one line (:func:`main`)."""
    name = f"psvs {args.command}"
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt as exc:
        # Ctrl-C, SIGTERM, SIGHUP: one line and the shell's status for the signal; files are written
        # atomically, so no output is left half-written (a write in progress removes its temporary file)
        return _interrupted(name, exc)
    except MeasurementError as exc:     # well-formed input that cannot give a right answer: say why, no number
        print(f"{name}: cannot measure: {_one_line(exc)}", file=sys.stderr)
        return 1
    except BrokenPipeError:
        # the reader of the output went away (``psvs ... | head``): nothing left to say, and nothing more
        # written to that pipe (Python would complain of it again when it flushes stdout at exit)
        with contextlib.suppress(OSError, ValueError, AttributeError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except (ValueError, TypeError, OSError, RigGeometryError) as exc:
        msg = _one_line(exc)
        if isinstance(exc, OSError) and exc.filename and str(exc.filename) not in msg:
            msg = f"{msg}: {exc.filename}"
        print(f"{name}: error: {msg}", file=sys.stderr)
        return 2
    except Exception as exc:
        signalled = signal_inside(exc)
        if signalled is not None:       # a signal that arrived inside compiled code (Numba wraps it)
            return _interrupted(name, signalled)
        if debug:
            raise
        return _internal_error(name, exc)


def signal_inside(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or termination an exception wraps (a SystemError "returned a result with an exception set"
    from a Numba kernel the signal's handler raised in), or None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _internal_error(name: str, exc: Exception) -> int:
    """One line naming an exception psvs did not expect and how to see where it came from; exit status 1."""
    text = str(exc).strip()
    what = f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__
    print(f"{name}: internal error: {what} ({DEBUG_ENV}=1 shows the traceback)", file=sys.stderr)
    return 1


def _one_line(exc: BaseException) -> str:
    """An exception's message as one line (its first), or its type's name when it has none."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def entry() -> NoReturn:
    """The ``psvs`` console script and ``python -m psvs``: :func:`main` with whole writes
    (:func:`_whole_writes`), then :func:`end_process`."""
    _whole_writes()
    argv = sys.argv[1:]
    try:
        code = main(argv)
    except SystemExit as exc:        # argparse's --help (0) and usage errors (2), its words already printed
        code = exc.code if isinstance(exc.code, int) else 0 if exc.code is None else 1
        if not isinstance(exc.code, int | None):
            print(exc.code, file=sys.stderr)
    try:
        end_process(code, f"psvs {argv[0]}" if argv and argv[0] in COMMANDS else "psvs")
    except KeyboardInterrupt:        # Ctrl-C while the output is flushed: the shell's status, no traceback
        os._exit(130)


def _whole_writes() -> None:
    """Unbuffered standard streams (``python -u``, PYTHONUNBUFFERED: many containers set it) write straight to
    their file, and Python's text layer ignores a short write's count: a result on stdout to a full disk or a
    closed pipe was cut short at exit 0 (an adversarial trial: 2 MB of an 18.7 MB ``psvs triangulate``). Each
    such stream is given a buffer that writes whole and says when it cannot, flushed at every line as before."""
    if sys.stderr is None:           # closed: psvs's one lines go nowhere, never onto stdout (print's default)
        sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - the process's own stream, open until it ends
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        raw = getattr(stream, "buffer", None)
        if isinstance(raw, io.RawIOBase):
            setattr(sys, name, io.TextIOWrapper(io.BufferedWriter(raw), encoding=stream.encoding,
                                                errors=stream.errors, line_buffering=True))


def end_process(code: int, name: str = "psvs") -> NoReturn:
    """End the process with ``code`` once the command is done: the standard streams flushed and the exit
    handlers run (a Rerun recording's, logging's), but without the interpreter's teardown of every module,
    which after a dense call (Numba's compiled kernels and thread pool, LLVM) took 0.15-0.2 s of a 1.4-1.9 s
    ``psvs disparity --depth`` (bench/bench_depth.py). Every file psvs writes is complete and in place before
    its command returns (written atomically). Output that cannot be written at the end (a full disk: one line
    naming it, status 2; a reader gone: status 141, nothing said, as during the command) is not lost silently.
    While another thread that is not a daemon still runs, or a stream is missing, the interpreter ends as
    usual."""
    try:
        code = _flushed(code, name)
    except (ValueError, AttributeError):           # a stream closed or none: the usual ending
        raise SystemExit(code) from None
    others = [t for t in threading.enumerate() if t is not threading.main_thread() and not t.daemon]
    run_exit_handlers = getattr(atexit, "_run_exitfuncs", None)      # CPython's, as its own ending runs them
    if others or run_exit_handlers is None:
        raise SystemExit(code)
    run_exit_handlers()
    with contextlib.suppress(OSError, ValueError, AttributeError):
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(code)


def _flushed(code: int, name: str) -> int:
    """The exit status once stdout and stderr are flushed: ``code``, or 141 when stdout's reader went away,
    2 (with one line) when it cannot be written; what could not be written is dropped (stdout then goes to
    the null device), so that nothing fails again at exit."""
    try:
        sys.stdout.flush()
    except OSError as exc:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        if isinstance(exc, BrokenPipeError):
            return code or 141
        if code == 0:                               # (a command that failed has said why)
            if sys.stderr is not None:
                with contextlib.suppress(OSError, ValueError):
                    print(f"{name}: error: the output could not be written: {exc.strerror or exc}", file=sys.stderr)
            code = 2
    with contextlib.suppress(OSError, ValueError, AttributeError):   # an error line that cannot be written,
        sys.stderr.flush()                                           # or no stderr: nothing to say it on
    return code


if __name__ == "__main__":
    entry()
