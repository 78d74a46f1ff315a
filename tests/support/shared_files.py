"""Files the test session's processes share: made once, by whichever process asks first, and read by all.

Under pytest-xdist two files' tests run in two workers; a costly input both need (a rendered video of a
1440x1080 build: three minutes) is rendered once. The folder belongs to the session: its name carries the
pytest process's id (a worker's parent), and that process removes it when the session ends (tests/conftest.py)."""
from __future__ import annotations

import fcntl
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path


def session_folder(pytest_pid: int | None = None) -> Path:
    """The session's shared folder: /tmp/psvs-tests-<pid of the pytest process> (under xdist, the workers'
    parent)."""
    if pytest_pid is None:
        pytest_pid = os.getppid() if os.environ.get("PYTEST_XDIST_WORKER") else os.getpid()
    return Path(tempfile.gettempdir()) / f"psvs-tests-{pytest_pid}"


def shared_file(name: str, make: Callable[[Path], object]) -> Path:
    """FOLDER/name, made by ``make(path)`` unless another process of the session made it; under an exclusive
    lock, so a second process asking meanwhile waits for the first one's file. ``make`` writes a file of
    ``name``'s suffix at the path it is given (a temporary name, moved into place when complete, so a process
    killed mid-way leaves no half-made file to be read)."""
    root = session_folder()
    root.mkdir(exist_ok=True)
    path = root / name
    with open(root / f".{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            part = root / f"part-{os.getpid()}-{name}"
            make(part)
            os.replace(part, path)
    return path


def remove_session_folder() -> None:
    """The session's shared folder removed (the pytest process, at the session's end)."""
    shutil.rmtree(session_folder(os.getpid()), ignore_errors=True)
