"""Run one named bad input through the command line, in process, and check the promise psvs makes of every
refusal: the exit status (1: the data cannot give a right answer; 2: bad input), exactly one line on
stderr (C-level output included: the runner captures file descriptors), no traceback, no file the command
was asked to write changed (each is planted beforehand with known bytes), nothing else written into the
scratch folder, and an answer within the hang limit."""
from __future__ import annotations

import shutil
import signal
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from psvs.cli.main import main
from tests.support.cli import user_cpu_s

#: A case taking longer than this hangs (a refusal must come before the work, in well under it).
HANG_S = 10.0
#: The wall-clock alarm: a case blocked (waiting, not working) this long is a hang. The 10 s limit itself is on
#: the user-mode CPU time the case uses (its own work, every thread: tests.support.cli.user_cpu_s).
WALL_S = 60.0
#: What a planted earlier output holds; the refusal must leave it so.
PLANTED = b"an earlier result that a refused command must not touch\n"
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@dataclass(frozen=True)
class Case:
    """One bad input.

    name : the case's id (what a failure names).
    argv : the command line after ``psvs`` (paths relative to the scratch folder).
    files : files to create first, {relative path: bytes, str, or a callable(folder) -> bytes | str}.
    exit : the exit status expected (1 or 2).
    says : a fragment the one-line message must hold (case-insensitive), '' for any.
    outputs : files the command would write: planted first, checked unchanged after.
    slow : a long end-to-end case (the README's test command runs it; .ci/latest does not).
    """

    name: str
    argv: tuple[str, ...]
    exit: int = 2
    says: str = ""
    files: dict = field(default_factory=dict)
    outputs: tuple[str, ...] = ()
    slow: bool = False


class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang(f"no answer within {WALL_S:g} s")


def _write(folder: Path, rel: str, content) -> None:
    path = folder / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    if callable(content):
        content = content(folder)
    path.write_bytes(content.encode() if isinstance(content, str) else content)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def run_case(case: Case, folder: Path, capfd, monkeypatch, prepare: Callable[[Path], None] | None = None) -> str:
    """Run ``case`` in the empty scratch ``folder``; assert the refusal's promise; return its message."""
    shutil.copytree(EXAMPLES, folder / "examples")
    if prepare is not None:
        prepare(folder)
    for rel, content in case.files.items():
        _write(folder, rel, content)
    for rel in case.outputs:
        _write(folder, rel, PLANTED)
    before = _snapshot(folder)
    monkeypatch.chdir(folder)
    capfd.readouterr()
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, WALL_S)
    t0 = user_cpu_s()
    try:
        code = main(list(case.argv))
    except SystemExit as exc:              # argparse's usage errors
        code = exc.code
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    elapsed = user_cpu_s() - t0
    out, err = capfd.readouterr()
    lines = err.strip().splitlines()
    assert "Traceback" not in out + err, err
    assert code == case.exit, f"exit {code}, expected {case.exit}: {err.strip()!r}"
    assert len(lines) == 1, f"{len(lines)} lines on stderr: {err!r}"
    assert case.says.lower() in lines[0].lower(), f"{lines[0]!r} does not say {case.says!r}"
    assert elapsed < HANG_S, f"{elapsed:.1f} s of CPU time (the limit: {HANG_S:g} s)"
    after = _snapshot(folder)
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    assert not changed, f"files changed or written by a refused command: {changed}"
    return lines[0]
