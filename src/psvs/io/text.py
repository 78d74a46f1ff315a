"""Reading a text file the user named, with a clear error when it is binary (e.g. a PNG given as CSV), and
checking that a path to read names a file (:func:`input_file`).

Text is UTF-8, with or without the byte-order mark that spreadsheet programs and some editors write first
("utf-8-sig"): the mark is dropped, so a CSV header's first column or a TOML file's first key reads as typed.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path


def input_file(path, what: str) -> Path:
    """``path`` as a Path when it names a regular file to read; otherwise FileNotFoundError("<what> not found:
    ..."), IsADirectoryError (a folder) or ValueError (a device, a pipe or a socket: psvs reads files it can
    read to their end), each naming ``what`` (e.g. "rig file", "image")."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{what} {path} is a folder, not a file")
    if path.exists() and not path.is_file():
        raise ValueError(f"{what} {path} is not a regular file (a device, a pipe or a socket)")
    if not path.is_file():
        raise FileNotFoundError(f"{what} not found: {path}")
    return path


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
