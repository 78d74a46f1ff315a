"""A small TOML writer for psvs's own files: readable, with inline number arrays.

Supports what our files hold: tables (dict), arrays of tables (list of dict), and values that are
bool, int, float (incl. nan/inf), str, or flat lists of those. Reading uses the standard ``tomllib``.
"""
from __future__ import annotations

import json
import math


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string: JSON's escapes are valid TOML escapes
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} {v!r} to TOML")


def _is_table_array(v) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def _emit(table: dict, prefix: str, out: list[str]) -> None:
    for k, v in table.items():
        if not isinstance(v, dict) and not _is_table_array(v):
            out.append(f"{k} = {_value(v)}")
    for k, v in table.items():
        name = f"{prefix}.{k}" if prefix else k
        if isinstance(v, dict):
            out += ["", f"[{name}]"]
            _emit(v, name, out)
        elif _is_table_array(v):
            for item in v:
                out += ["", f"[[{name}]]"]
                _emit(item, name, out)


def dumps_toml(data: dict) -> str:
    """TOML text of a nested dict (keys must be bare: letters, digits, '_' and '-').

    Examples
    --------
    >>> print(dumps_toml({"camera": {"focal_length_mm": 11.3, "image_size_px": [640, 480]}}), end="")
    [camera]
    focal_length_mm = 11.3
    image_size_px = [640, 480]
    """
    out: list[str] = []
    _emit(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"
