"""psvs's TOML files: reading with errors that name the file (``tomllib``), writing with ``tomli-w``."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

from psvs.io.text import read_text


def load_toml(path, what: str) -> dict:
    """Parse a TOML file (or JSON, by its suffix); raise FileNotFoundError("<what> file not found: ...")
    or ValueError("<path>: malformed TOML: ...")."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} file not found: {path}")
    is_json = path.suffix.lower() == ".json"
    text = read_text(path, "JSON" if is_json else "TOML")
    try:
        return json.loads(text) if is_json else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: malformed {'JSON' if is_json else 'TOML'}: {exc}") from None


def single_table(data: dict, table: str, keys: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict:
    """The one table ``[table]`` of a file's ``data``, with every one of ``keys`` and any of ``optional``;
    ValueError naming the first unknown or missing key otherwise."""
    if set(data) != {table} or not isinstance(data[table], dict):
        raise ValueError(f"expected one table [{table}]")
    t = data[table]
    unknown = sorted(set(t) - set(keys) - set(optional))
    if unknown:
        raise ValueError(f"unknown key {table}.{unknown[0]} (allowed: {', '.join((*keys, *optional))})")
    missing = [k for k in keys if k not in t]
    if missing:
        raise ValueError(f"missing key {table}.{missing[0]}")
    return t


def load_table(path, what: str, table: str, keys: tuple[str, ...], optional: tuple[str, ...] = (), parse=None):
    """Read a file of one table ``[table]`` with every one of ``keys`` and any of ``optional``
    (:func:`single_table`), and build its object with ``parse(table)`` (the table itself without);
    ValueError names the file and the key."""
    path = Path(path)
    data = load_toml(path, what)
    try:
        t = single_table(data, table, keys, optional)
        return t if parse is None else parse(t)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path}: {exc}") from None


def dumps_toml(data: dict) -> str:
    """TOML text of a nested dict of plain Python values (``tomli-w``; NumPy scalars must be converted
    first: a TypeError names the value, so nothing unreadable is ever written).

    Examples
    --------
    >>> print(dumps_toml({"camera": {"focal_length_mm": 11.3, "image_size_px": [640, 480]}}), end="")
    [camera]
    focal_length_mm = 11.3
    image_size_px = [
        640,
        480,
    ]
    """
    import tomli_w
    return tomli_w.dumps(data)
