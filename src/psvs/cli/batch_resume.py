"""What a second ``psvs batch`` over a run folder checks before it skips a frame: that the frame's files are
there and read back as its row says. A result file deleted, cut short or written over since (an adversarial
trial: the run still said "1 ok, 0 computed now" and left it missing) is computed again."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["damaged_results"]


def _reads_back(path: Path, row: dict) -> str:
    """Why the result file ``path`` does not hold what its ``row`` says ("" when it does)."""
    if not path.is_file() or path.stat().st_size == 0:
        return "missing" if not path.exists() else "empty"
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
