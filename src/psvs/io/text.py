"""Reading a text file the user named, with a clear error when it is binary (e.g. a PNG given as CSV)."""
from __future__ import annotations

from pathlib import Path


def read_text(path, kind: str) -> str:
    """The UTF-8 text of ``path``; ValueError("<path>: not a <kind> file ...") when it does not decode."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a {kind} file (it is not UTF-8 text; an image?)") from None
