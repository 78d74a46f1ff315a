"""What a second ``psvs batch`` over a run folder checks before it skips a frame: that the frame's files are
there and hold what they held when its row was written. A result file deleted, cut short or written over since
(adversarial trials: the run still said "1 ok, 0 computed now" and left it missing; another frame's map copied
over one, a view cut short or replaced by text, passed) is computed again.

Each ``ok`` row names its files' SHA-256 (``files_sha256``: ``name=hex`` pairs joined by ``;``, written by
:func:`files_digest` when the frame's files are complete); a row from an earlier psvs without it is checked
as before, by reading each file back (a ``.npy`` loads, a ``.json``'s Z is the row's)."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

__all__ = ["damaged_results", "files_digest"]

_CHUNK = 1 << 20


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(_CHUNK):
            h.update(block)
    return h.hexdigest()


def files_digest(paths) -> str:
    """``name=sha256;...`` of the files ``paths`` that exist (by file name, in the order given)."""
    return ";".join(f"{Path(p).name}={_sha256(Path(p))}" for p in paths if Path(p).is_file())


def _held_digests(row: dict) -> dict[str, str] | None:
    """The row's ``files_sha256`` as {file name: hex}; None when the row has none (an earlier psvs's)."""
    text = row.get("files_sha256")
    if not isinstance(text, str):
        return None
    return dict(item.split("=", 1) for item in text.split(";") if "=" in item)


def _reads_back(path: Path, row: dict) -> str:
    """Why the result file ``path`` does not hold what its ``row`` says ("" when it does)."""
    if not path.is_file() or path.stat().st_size == 0:
        return "missing" if not path.exists() else "empty"
    held = _held_digests(row)
    if held is not None:
        if path.name not in held:
            return "not among the files its row names"
        return "" if _sha256(path) == held[path.name] else "changed since it was written (its SHA-256 differs)"
    try:
        if path.suffix == ".npy":
            np.load(path, mmap_mode="r")
        elif path.suffix == ".json":
            held = json.loads(path.read_text())
            z = row.get("Z_mm")
            if isinstance(z, float) and not (isinstance(held, dict) and held.get("Z_mm") == z):
                return f"holds Z {held.get('Z_mm') if isinstance(held, dict) else None} mm, its row {z} mm"
    except (ValueError, OSError) as exc:
        return f"unreadable ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"
    return ""


def damaged_results(job: dict, table, frame_outputs) -> dict[str, str]:
    """The keys of the frames stored as ``ok`` in ``table`` (the run's results, or None) whose files do not
    read back (:func:`_reads_back`), each with the first file and why; ``frame_outputs(job, key)`` lists the
    files a frame writes."""
    if table is None:
        return {}
    out = {}
    for row in table.to_pylist():
        if row.get("status") != "ok":
            continue
        for f in frame_outputs(job, row["key"]):
            why = _reads_back(Path(f), row)
            if why:
                out[row["key"]] = f"{Path(f).name}: {why}"
                break
    return out
