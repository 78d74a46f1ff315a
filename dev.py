#!/usr/bin/env python3
"""Set up and run psvs with nothing but Python >= 3.11 and git.

    python3 dev.py demo          # the main demo
    python3 dev.py test          # the whole test suite (what CI runs)
    python3 dev.py test --quick  # the quick tier, for the edit-test loop (tests/support/durations.py)
    python3 dev.py bench         # benchmarks -> docs/benchmarks.md
    python3 dev.py psvs ARGS...  # any psvs command inside the project's virtualenv

The first call creates ``.venv`` and installs psvs itself (editable) with the pinned
``requirements.lock``: what psvs needs, enough for ``demo`` and ``psvs``. ``test`` and ``bench`` add the
pinned extras of ``requirements-dev.lock`` (the test tools, Basler's pypylon, the CAD kernel, Rerun). Later calls
reuse the virtualenv and reinstall only when a lock file or pyproject.toml change.
"""
from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
STAMP = VENV / ".psvs-installed"


def _python() -> Path:
    return VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


#: What each level installs: ``core`` for the demo and psvs commands, ``full`` for the tests and benchmarks.
LOCKS = {"core": ("requirements.lock",), "full": ("requirements.lock", "requirements-dev.lock")}


def _fingerprint(level: str) -> str:
    h = hashlib.sha256(level.encode())
    for name in (*LOCKS[level], "pyproject.toml"):
        h.update((ROOT / name).read_bytes())
    return h.hexdigest()


def _installed() -> set[str]:
    """The fingerprints of what .venv holds now (one line per level installed)."""
    return set(STAMP.read_text().split()) if STAMP.exists() else set()


def ensure_env(level: str = "full") -> Path:
    """Create the virtualenv and install the pinned dependencies of ``level`` when needed; return its
    python. A full install also serves ``core``."""
    if sys.version_info < (3, 11):
        sys.exit(f"dev.py: Python >= 3.11 is needed, this is {sys.version.split()[0]}")
    py = _python()
    want = _fingerprint(level)
    have = _installed() if py.exists() else set()
    if want in have or (level == "core" and _fingerprint("full") in have):
        return py
    if not py.exists():
        print("dev.py: creating .venv ...", flush=True)
        venv.create(VENV, with_pip=True)
    pip = [str(py), "-m", "pip", "install", "--quiet", "--disable-pip-version-check"]
    what = "psvs's pinned dependencies" if level == "core" else "psvs's pinned dependencies and its extras"
    print(f"dev.py: installing {what} ...", flush=True)
    locks = [arg for name in LOCKS[level] for arg in ("-r", str(ROOT / name))]
    subprocess.run(pip + locks, check=True)
    subprocess.run(pip + ["--no-deps", "--no-build-isolation", "-e", str(ROOT)], check=True)
    STAMP.write_text("\n".join(sorted({want, _fingerprint("core")} if level == "full" else {want})) + "\n")
    return py


def run_child(args: list[str], **kwargs) -> int:
    """Run a command and return its exit status. Ctrl-C reaches the child (the terminal sends SIGINT to
    the whole process group; a SIGINT sent to dev.py alone is passed on), and dev.py waits for it to stop
    cleanly instead of killing it: status 130, no traceback from dev.py."""
    proc = subprocess.Popen(args, **kwargs)
    while True:
        try:
            code = proc.wait()
            break
        except KeyboardInterrupt:
            try:
                proc.send_signal(signal.SIGINT)
            except ProcessLookupError:
                pass
    return 130 if code == -signal.SIGINT else code


def _workers(rest: list[str]) -> list[str]:
    """pytest-xdist options: one worker per core (at most 4), a test file's tests on one worker (they share
    its costly fixtures), the files handed out in the order collected (longest first by the record:
    tests/support/durations.py); none when the caller chose (-n, -p no:xdist) or there is one core."""
    n = min(4, os.cpu_count() or 1)
    chosen = any(a.startswith("-n") or a == "--numprocesses" or "xdist" in a for a in rest)
    return [] if chosen or n < 2 else ["-n", str(n), "--dist", "loadfile", "--no-loadscope-reorder"]


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in {"demo", "test", "bench", "psvs"}:
        print(__doc__, file=sys.stderr)
        return 2
    cmd, rest = argv[0], argv[1:]
    py = str(ensure_env("full" if cmd in ("test", "bench") else "core"))
    env = dict(os.environ, MPLBACKEND="Agg")
    if cmd == "demo":
        args = [py, "-m", "psvs", "demo", *rest]
    elif cmd == "test":
        workers = _workers(rest)
        # the whole suite keeps the record of each test's time that --quick chooses from (tests/support/durations.py)
        record = [] if rest else ["--record-durations", str(ROOT / "tests" / "durations.json")]
        args = [py, "-m", "pytest", "-q", *workers, *record, *rest]
        if workers:    # the cores shared out: each worker's Numba kernels (tests/conftest.py) and BLAS on its share
            share = str(max(1, (os.cpu_count() or 1) // int(workers[1])))
            for var in ("PSVS_WORKER_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
                env.setdefault(var, share)
    elif cmd == "bench":
        args = [py, str(ROOT / "bench" / "run.py"), *rest]
    else:
        args = [py, "-m", "psvs", *rest]
    # psvs and the demo run where the user is (relative paths mean what they typed); tests and benchmarks
    # run in the repository
    return run_child(args, cwd=ROOT if cmd in ("test", "bench") else Path.cwd(), env=env)


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except KeyboardInterrupt:           # Ctrl-C while setting up the virtualenv
        print("\ndev.py: interrupted", file=sys.stderr)
        sys.exit(130)
