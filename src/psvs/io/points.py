"""CSV tables of correspondences (u_l, v_l, u_r, v_r px) and of triangulated points (X, Y, Z mm, valid)."""
from __future__ import annotations

import io

import numpy as np

from psvs._budget import check_memory
from psvs.io.atomic import write_atomic
from psvs.io.text import input_file, read_csv_rows

MATCH_COLUMNS = ("u_l", "v_l", "u_r", "v_r")
POINT_COLUMNS = ("X_mm", "Y_mm", "Z_mm", "valid")


#: Peak bytes per row of a matches table while it is read and triangulated (measured: 1e6 rows through the exact
#: model reached 795 MB; rounded up).
ROW_BYTES = 1000


def check_rows_memory(path, row_bytes: float = ROW_BYTES, what: str | None = None) -> int:
    """The rows (lines) of the file at ``path``, counted without parsing it; ValueError naming the file when
    reading and working on that many rows at ``row_bytes`` each would not fit in memory (psvs._budget)."""
    path = input_file(path, "points file")
    rows = 0
    with path.open("rb") as f:
        while chunk := f.read(1 << 22):
            rows += chunk.count(b"\n")
    check_memory(rows * row_bytes, what or f"{path}: {rows} rows")
    return rows


def read_matches_csv(path) -> tuple[np.ndarray, np.ndarray]:
    """Read a CSV with header columns ``u_l,v_l,u_r,v_r`` (px; other columns ignored).

    Returns ``left_px`` (N, 2) and ``right_px`` (N, 2). Empty cells and ``nan`` become NaN.
    """
    arr = read_csv_columns(path, MATCH_COLUMNS)
    return arr[:, :2], arr[:, 2:]


def read_csv_columns(path, columns: tuple[str, ...]) -> np.ndarray:
    """The named numeric columns of a CSV with a header, shape (N, len(columns)); other columns ignored."""
    path = input_file(path, "points file")
    table = read_csv_rows(path)
    if not table:
        raise ValueError(f"{path}: empty file, expected a header {','.join(columns)}")
    header = [h.strip() for h in table[0]]
    twice = sorted({c for c in columns if header.count(c) > 1})
    if twice:
        raise ValueError(f"{path}: column(s) {', '.join(twice)} appear more than once in the header: which one "
                         "holds the values is not certain")
    missing = [c for c in columns if c not in header]
    if missing:
        raise ValueError(f"{path}: missing column(s) {', '.join(missing)}; expected header "
                         f"{','.join(columns)}, got {','.join(header)}")
    idx = [header.index(c) for c in columns]
    rows = []
    for lineno, row in enumerate(table[1:], start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) != len(header):    # a cell short, or one more than the header names: which is which?
            raise ValueError(f"{path}:{lineno}: expected {len(header)} columns as the header names, got {len(row)}"
                             + (" (a trailing comma?)" if len(row) == len(header) + 1 and not row[-1].strip()
                                else ""))
        bad = next((row[i] for i in idx if not _is_float(row[i])), None)
        if bad is not None:
            raise ValueError(f"{path}:{lineno}: not a number: {bad!r}")
        rows.append([float(row[i]) if row[i].strip() else np.nan for i in idx])
    return np.array(rows, dtype=float).reshape(-1, len(columns))


def _is_float(text: str) -> bool:
    """A decimal number as a CSV holds one (or an empty cell); not Python's own literals beyond it: ``4_00``
    (an adversarial trial: read as 400 where ``0x1p8`` was refused)."""
    if "_" in text:
        return False
    try:
        float(text)
        return True
    except ValueError:
        return not text.strip()


def points_csv_text(points_mm: np.ndarray, valid: np.ndarray, z_sigma_mm: np.ndarray | None = None) -> str:
    """CSV text with columns ``X_mm,Y_mm,Z_mm,valid`` (valid as 1/0, invalid rows' coordinates nan), with
    ``z_sigma_mm`` (N,) a column ``Z_sigma_mm`` before ``valid`` (the depth's uncertainty, mm; written as given:
    ``psvs triangulate`` leaves it nan on invalid rows)."""
    buf = io.StringIO()
    columns = POINT_COLUMNS if z_sigma_mm is None else POINT_COLUMNS[:3] + ("Z_sigma_mm",) + POINT_COLUMNS[3:]
    buf.write(",".join(columns) + "\n")
    sigmas = [None] * len(valid) if z_sigma_mm is None else z_sigma_mm
    for (x, y, z), s, ok in zip(points_mm, sigmas, valid, strict=True):
        sigma = "" if s is None else f"{s:.6g},"
        buf.write(f"{x:.15g},{y:.15g},{z:.15g},{sigma}{int(bool(ok))}\n")
    return buf.getvalue()


def write_points_csv(path, points_mm: np.ndarray, valid: np.ndarray, z_sigma_mm: np.ndarray | None = None) -> None:
    """Write triangulated points atomically (see :func:`points_csv_text`)."""
    write_atomic(path, points_csv_text(points_mm, valid, z_sigma_mm))
