"""Atomic file writes: a file is either fully written or left as it was; and, inside :func:`output_batch`,
a command's outputs land together or not at all."""
from __future__ import annotations

import contextvars
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

# (temporary file, destination) pairs of the open batch, or None outside a batch
_BATCH: contextvars.ContextVar[list | None] = contextvars.ContextVar("psvs_output_batch", default=None)


def write_atomic(path, data: str | bytes, *, batch: bool = True) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``.

    A crash or error part-way leaves any earlier file at ``path`` untouched. Inside :func:`output_batch` the
    temporary file is only renamed into place when the whole batch has been written; with ``batch=False``
    at once, as outside a batch (a cache file, which is none of a command's outputs).
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {path.parent}")
    mode = "wb" if isinstance(data, bytes) else "w"
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:   # name the file the user asked for, not the hidden temporary one
        raise type(exc)(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the permissions open() would
        with os.fdopen(fd, mode, **({} if mode == "wb" else {"encoding": "utf-8", "newline": ""})) as fh:
            fh.write(data)
        pending = _BATCH.get() if batch else None
        if pending is not None:
            pending.append((tmp, path))
            return
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise type(exc)(f"cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextmanager
def output_batch():
    """Every :func:`write_atomic` in the block goes to its temporary file; when the block ends normally all
    are renamed into place, and when it raises (a later output cannot be written, bad input found late,
    Ctrl-C) none is: the earlier files stay as they were. Batches do not nest (an inner one joins the outer)."""
    if _BATCH.get() is not None:
        yield
        return
    pending: list = []
    token = _BATCH.set(pending)
    try:
        yield
    except BaseException:
        for tmp, _ in pending:
            Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        _BATCH.reset(token)
    _land(pending)


def _land(pending: list) -> None:
    """Rename a batch's temporary files into place: none when a destination is a folder (IsADirectoryError
    naming it, every temporary file removed), and when a rename fails part-way the rest are removed (the files
    renamed before it stay: a folder cannot be replaced atomically as a whole)."""
    folders = [path for _, path in pending if Path(path).is_dir()]
    try:
        if folders:
            raise IsADirectoryError(f"cannot write {folders[0]}: it is a folder")
        for k, (tmp, path) in enumerate(pending):
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise type(exc)(f"cannot write {path}: {exc.strerror or exc}") from None
            pending[k] = (None, path)
    except BaseException:
        for tmp, _ in pending:
            if tmp is not None:
                Path(tmp).unlink(missing_ok=True)
        raise


def check_output_folder(path, option: str = "output folder") -> Path:
    """Validate an output folder before any work: not a file (ValueError), and writable (the folder, or the
    nearest existing folder above it, which psvs will create it in; PermissionError). Returns the path; creates
    nothing. The command line's ``-o`` folders and the web page's capture folder."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ValueError(f"{option} {p} is a file")
    existing = p
    while not existing.exists():
        existing = existing.parent
    check_writable(existing, f"{option} {p}")
    return p


def check_writable(folder, what: str) -> None:
    """PermissionError naming ``what`` unless a file can be made in the existing ``folder``: tried, with an
    empty file of a hidden name removed at once (the permission bits do not tell: root may write anywhere
    they say, yet not in /proc or on a read-only mount)."""
    folder = Path(folder)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(f"cannot write {what}: permission denied")
    try:
        fd, probe = tempfile.mkstemp(prefix=".psvs-probe-", dir=folder)
    except OSError as exc:
        raise PermissionError(f"cannot write {what}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)
