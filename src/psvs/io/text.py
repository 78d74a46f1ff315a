"""Reading a text file the user named, with a clear error when it is binary (e.g. a PNG given as CSV).

Text is UTF-8, with or without the byte-order mark that spreadsheet programs and some editors write first
("utf-8-sig"): the mark is dropped, so a CSV header's first column or a TOML file's first key reads as typed.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path


def read_text(path, kind: str) -> str:
    """The UTF-8 text of ``path`` without a leading byte-order mark; ValueError("<path>: not a <kind> file
    ...") when it does not decode."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a {kind} file (it is not UTF-8 text; an image?)") from None


def read_csv_rows(path, kind: str = "CSV") -> list[list[str]]:
    """The rows of a CSV file (:func:`read_text`, so a byte-order mark is dropped), each a list of its cells
    as written; ValueError naming the file and the line for what the ``csv`` module refuses (a cell longer
    than its field size limit, 128 Ki characters)."""
    path = Path(path)
    reader = csv.reader(io.StringIO(read_text(path, kind), newline=""))
    try:
        return list(reader)
    except csv.Error as exc:
        raise ValueError(f"{path}:{reader.line_num}: not a {kind} file: {exc}") from None
