"""A run's folder: its parameters (``study.json``) and its results in Parquet, one small part file per batch
of finished results (``parts/part-NNNNNN.parquet``, each written atomically), merged into ``results.parquet``
when a run completes. A row is one task's flat dict of scalars with its ``key``; a key is done when any file
holds its row, so a run stopped at any point (Ctrl-C, a killed process, a lost machine) keeps every result
already written and a later run computes only the rest."""
from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from psvs.io.atomic import write_atomic

PARAMS_FILE = "study.json"
RESULTS_FILE = "results.parquet"
PARTS_DIR = "parts"
KEY = "key"
#: A row's values: what a Parquet column of scalars holds.
SCALARS = (bool, int, float, str, type(None))


def check_run_folder(out, command: str) -> Path:
    """The folder a run writes (resolved): ValueError when it is a file, FileNotFoundError when its parent is
    missing; nothing is created."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"-o {out} is a file; {command} writes a folder")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"output folder's parent does not exist: {out.parent}")
    return out.resolve()


def record_params(out_dir: Path, params: dict) -> None:
    """Write ``params`` (JSON-able) to ``out_dir/study.json``, or check that the file already there holds the
    same: a folder made with other parameters is refused in one line naming the first difference (its results
    would mix two runs)."""
    if not check_params(out_dir, params):
        text = json.dumps(params, sort_keys=True, indent=1, allow_nan=False)
        write_atomic(Path(out_dir) / PARAMS_FILE, text + "\n")


def check_params(out_dir: Path, params: dict) -> bool:
    """Whether ``out_dir`` holds a run made with ``params`` (False: no run there yet); ValueError when it holds
    one made with other parameters, or a parameter file that is not one. Nothing is written."""
    path = Path(out_dir) / PARAMS_FILE
    wanted = json.loads(json.dumps(params, sort_keys=True, allow_nan=False))
    if not path.exists():
        return False
    try:
        held = json.loads(path.read_text(encoding="utf-8-sig"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path} is not a run's parameter file ({exc}); give another folder") from None
    if held != wanted:
        name, there, now = _first_difference(held, wanted)
        raise ValueError(f"{out_dir} holds a run made with other parameters ({name}: {there!r} there, {now!r} "
                         f"now); give another folder, or the same parameters to resume")
    return True


def _first_difference(a, b, name: str = "the parameters") -> tuple:
    """(dotted name, value in a, value in b) of the first entry where nested dicts a and b differ."""
    if not isinstance(a, dict) or not isinstance(b, dict):
        return name, a, b
    k = next(k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k))
    return _first_difference(a.get(k), b.get(k), k if name == "the parameters" else f"{name}.{k}")


def check_row(row, key) -> dict:
    """``row`` as a flat dict of Parquet scalars (numpy scalars unwrapped) with ``key`` added; TypeError naming
    what is not one."""
    if not isinstance(row, dict):
        raise TypeError(f"a task must return a dict of scalars, got {type(row).__name__} for key {key!r}")
    out = {KEY: key}
    for name, value in row.items():
        if not isinstance(name, str) or name == KEY:
            raise TypeError(f"task result for key {key!r}: column names are strings other than {KEY!r}, got {name!r}")
        if isinstance(value, np.generic):
            value = value.item()          # a numpy scalar
        if not isinstance(value, SCALARS):
            raise TypeError(f"task result for key {key!r}: {name} is a {type(value).__name__}, not a scalar")
        out[name] = value
    return out


class ResultStore:
    """The Parquet files of one run folder (see the module's docstring)."""

    def __init__(self, out_dir):
        self.out_dir = Path(out_dir)
        self.parts = self.out_dir / PARTS_DIR
        self._next = None

    def _part_files(self) -> list[Path]:
        return sorted(self.parts.glob("part-*.parquet")) if self.parts.is_dir() else []

    def append(self, rows: list[dict]) -> Path | None:
        """Write ``rows`` as one new part file, atomically; its path (None for no rows)."""
        if not rows:
            return None
        self.parts.mkdir(exist_ok=True)
        if self._next is None:
            files = self._part_files()
            self._next = int(files[-1].stem.split("-")[1]) + 1 if files else 0
        path = self.parts / f"part-{self._next:06d}.parquet"
        self._next += 1
        _write_table(path, pa.Table.from_pylist(rows))
        return path

    def read(self) -> pa.Table | None:
        """Every row written (results.parquet, then the parts in order), each key once (its first row), sorted
        by key; None when nothing is written yet."""
        files = ([self.out_dir / RESULTS_FILE] if (self.out_dir / RESULTS_FILE).is_file() else [])
        tables = [pq.read_table(f) for f in files + self._part_files()]
        tables = [t for t in tables if t.num_rows]
        if not tables:
            return None
        table = pa.concat_tables(tables, promote_options="permissive")
        seen, keep = set(), []
        for i, k in enumerate(table.column(KEY).to_pylist()):
            if k not in seen:
                seen.add(k)
                keep.append(i)
        return table.take(keep).sort_by(KEY)

    def done_keys(self) -> set:
        """The keys of every task whose result is stored; empty before the first."""
        table = self.read()
        return set() if table is None else set(table.column(KEY).to_pylist())

    def compact(self) -> None:
        """Merge every part into results.parquet (written atomically before the parts are removed: a crash in
        between leaves rows twice, which :meth:`read` reads once)."""
        parts = self._part_files()
        if not parts:
            return
        table = self.read()
        _write_table(self.out_dir / RESULTS_FILE, table)
        for p in parts:
            p.unlink(missing_ok=True)
        if not any(self.parts.iterdir()):
            self.parts.rmdir()

    def forget(self, keys) -> None:
        """Drop the rows of ``keys`` (their tasks are run again by the next run): the parts merged and
        results.parquet written again without them, atomically."""
        keys = set(keys)
        if not keys:
            return
        self.compact()
        table = self.read()
        if table is None:
            return
        keep = [i for i, k in enumerate(table.column(KEY).to_pylist()) if k not in keys]
        # typed: an empty list alone is null to Arrow, and taking it failed (every row forgotten: a trial)
        _write_table(self.out_dir / RESULTS_FILE, table.take(pa.array(keep, type=pa.int64())))


def _write_table(path: Path, table: pa.Table) -> None:
    buf = io.BytesIO()
    pq.write_table(table, buf)
    write_atomic(path, buf.getvalue())


def read_results(out_dir) -> pa.Table:
    """The results of the run in ``out_dir``: one row per finished key (column ``key`` and the task's
    columns), sorted by key; FileNotFoundError when the folder holds no run, an empty table when nothing
    finished yet."""
    out_dir = Path(out_dir)
    if not (out_dir / PARAMS_FILE).is_file():
        raise FileNotFoundError(f"no run in {out_dir} (no {PARAMS_FILE})")
    table = ResultStore(out_dir).read()
    return pa.table({KEY: pa.array([], pa.string())}) if table is None else table


def finite_or_none(x: float) -> float | None:
    """A float for a results column: None for NaN or infinity (Parquet holds them, JSON does not)."""
    return float(x) if x is not None and math.isfinite(x) else None
