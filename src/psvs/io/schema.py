"""The one reader of psvs's tables (TOML or JSON files, uploads): keys, types and bounds checked alike.

A table's keys are checked by :func:`check_keys` ("unknown key WHERE.KEY (allowed: ...)", "missing key
WHERE.KEY", "[WHERE] must be a table"); a table whose every key is a plain value is read by
:func:`read_fields` from a schema of :class:`Field` (type, bounds, default), each value checked by
:meth:`Field.value`; a wrong type ("WHERE.KEY must be a finite number, got str 'x'") and a value out of
bounds ("WHERE.KEY must be > 0, got -1") are a ValueError, as a bad value in any file psvs reads. Checks
across keys (far beyond near) stay with the reader that knows them. Readers on it: target files, camera
acquisition tables, tolerance studies; rig and scene files check their values in their own readers still.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

#: A :class:`Field` without a default must be given.
REQUIRED = object()
KINDS = ("number", "integer", "string", "flag", "table", "any")


@dataclass(frozen=True)
class Field:
    """One key of a table: ``kind`` (number: a finite float; integer: a whole number; string; flag: true or
    false; table: a nested table, its keys the reader's; any: kept as read, e.g. what a file records but
    psvs does not apply), inclusive bounds ``low``/``high`` (``low_open``: the low bound excluded), ``choices`` (a
    string's allowed values), ``default`` (:data:`REQUIRED`: the key must be given; None: it may be left out
    and is then absent from what :func:`read_fields` returns) and a ``note`` named in a type error."""

    kind: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple = ()
    default: object = None
    note: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Field kind must be one of {', '.join(KINDS)}, got {self.kind!r}")

    def value(self, v, key: str):
        """``v`` as this field's type (float, int, str or bool), checked; ``key`` names it in the error."""
        note = f" ({self.note})" if self.note else ""
        if self.kind == "any":
            return v
        if self.kind == "table":
            if not isinstance(v, dict):
                raise ValueError(f"[{key}] must be a table{note}, got {type(v).__name__}")   # as check_keys
            return v
        if self.kind == "flag":
            if not isinstance(v, bool):
                raise ValueError(f"{key} must be true or false, got {v!r}")
            return v
        if self.kind == "string":
            if not isinstance(v, str):
                raise ValueError(f"{key} must be a string{note}, got {type(v).__name__} {v!r}")
            if self.choices and v not in self.choices:
                raise ValueError(f"{key} must be one of {', '.join(map(str, self.choices))}, got {v!r}")
            return v
        if self.kind == "integer":
            if isinstance(v, bool) or not isinstance(v, int):
                raise ValueError(f"{key} must be a whole number{note}, got {type(v).__name__} {v!r}")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"{key} must be a finite number{note}, got {type(v).__name__} {v!r}")
        low_bad = self.low is not None and (v < self.low or (self.low_open and v == self.low))
        if low_bad or (self.high is not None and v > self.high):
            whole = "a whole number " if self.kind == "integer" else ""
            raise ValueError(f"{key} must be {whole}{self.bounds()}, got {v!r}")
        return int(v) if self.kind == "integer" else float(v)

    def bounds(self) -> str:
        """The allowed range in words: "> 0", ">= 1", "<= 60", "1-50", "> 0 and <= 3"."""
        low = None if self.low is None else f"{'>' if self.low_open else '>='} {self.low:g}"
        high = None if self.high is None else f"<= {self.high:g}"
        if low and high:
            return f"{self.low:g}-{self.high:g}" if not self.low_open else f"{low} and {high}"
        return low or high or "any"


def read_fields(table, where: str, fields: dict[str, Field], what: str = "") -> dict:
    """The values of ``table`` (a dict read from a file) under the schema ``fields``: every key known
    (:func:`check_keys`), every value checked (:meth:`Field.value`), defaults filled in; ``where`` is the
    table's path in its file ("" at the top), ``what`` names its kind in a key error."""
    required = tuple(k for k, f in fields.items() if f.default is REQUIRED)
    check_keys(table, where, required, tuple(k for k in fields if k not in required), what)
    out = {}
    for k, f in fields.items():
        if k in table:
            out[k] = f.value(table[k], _dotted(where, k))
        elif f.default is not None and f.default is not REQUIRED:
            out[k] = f.default
    return out


def check_keys(table, where: str, required=(), optional=(), what: str = "") -> dict:
    """``table`` when it is a table (dict) with every key of ``required`` and no key outside ``required`` and
    ``optional``; else ValueError in psvs's one wording for every file it reads: "[WHERE] must be a table",
    "unknown key WHERE.KEY (allowed: ...)", "missing key WHERE.KEY" (``what``, e.g. a target's kind, is named
    in both: "... for a charuco", "(a charuco needs ...)"). ``where`` is the table's path in its file ("" at
    the top)."""
    if not isinstance(table, dict):
        raise ValueError(f"[{where}] must be a table, got {type(table).__name__}")
    allowed = (*required, *optional)
    unknown = sorted((k for k in table if k not in allowed), key=str)
    if unknown:
        raise ValueError(f"unknown key {_dotted(where, unknown[0])}{f' for a {what}' if what else ''} "
                         f"(allowed: {', '.join(map(str, allowed))})")
    missing = [k for k in required if k not in table]
    if missing:
        needs = f" (a {what} needs {', '.join(required)})" if what else ""
        raise ValueError(f"missing key {_dotted(where, missing[0])}{needs}")
    return table


def _dotted(where: str, key) -> str:
    return f"{where}.{key}" if where else str(key)
