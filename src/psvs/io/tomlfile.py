"""psvs's TOML files: reading with errors that name the file (``tomllib``), writing with ``tomlkit``.

Written files lay arrays out as the shipped rig files do: an array stays on one line when it holds at most
:data:`SHORT_ARRAY` numbers (a rig's pairs, triples and the lens's five terms, whatever their digits) or its
line fits in :data:`LINE_CHARS` characters; a longer one gets one item per line (a 4 x 4 matrix one row per
line). Numbers are written as Python's ``repr``, which reads back as the same float.
"""
from __future__ import annotations

import json
import tomllib
from collections.abc import MutableMapping
from pathlib import Path

import numpy as np

from psvs.io.schema import check_keys
from psvs.io.text import input_file, read_text


def load_toml(path, what: str) -> dict:
    """Parse a TOML file (or JSON, by its suffix; UTF-8, a byte-order mark allowed); raise
    FileNotFoundError("<what> file not found: ..."), IsADirectoryError (a folder), ValueError (a device, a
    pipe: psvs reads files it can read to their end) or ValueError("<path>: malformed TOML: ...").

    Arrays or tables nested thousands deep exhaust the parsers' recursion (RecursionError): that is
    "<path>: malformed TOML: nested too deep", as no psvs file nests more than a few levels."""
    path = input_file(path, f"{what} file")
    kind = "JSON" if path.suffix.lower() == ".json" else "TOML"
    return parse_text(read_text(path, kind), str(path), kind)


def parse_text(text: str, where: str, kind: str = "TOML") -> dict:
    """Parse TOML (or JSON: ``kind``) text that did not come from a file (e.g. a web page's upload); a
    leading byte-order mark is dropped; ValueError("<where>: malformed <kind>: ...") as :func:`load_toml`."""
    text = text.removeprefix("\ufeff")
    try:
        return json.loads(text, object_pairs_hook=_unique_keys) if kind == "JSON" else tomllib.loads(text)
    except _DuplicateKey as exc:
        raise ValueError(f"{where}: malformed {kind}: {exc}") from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{where}: malformed {kind}: {exc}") from None
    except RecursionError:
        raise ValueError(f"{where}: malformed {kind}: nested too deep") from None
    except ValueError as exc:     # Python's own limits (an integer of thousands of digits)
        why = (str(exc).splitlines() or [type(exc).__name__])[0].strip("'\"").split(";")[0]
        raise ValueError(f"{where}: malformed {kind}: {why}") from None


class _DuplicateKey(ValueError):
    pass


def _unique_keys(pairs: list) -> dict:
    """A JSON object as a dict, refusing a key given twice (JSON keeps the last silently, TOML refuses it: a
    rig file with two "mirrors" objects read as one of them; a trial)."""
    out = {}
    for k, v in pairs:
        if k in out:
            raise _DuplicateKey(f"key {k!r} is given twice in one object")
        out[k] = v
    return out


def single_table(data: dict, table: str, keys: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict:
    """The one table ``[table]`` of a file's ``data``, with every one of ``keys`` and any of ``optional``;
    ValueError naming the first unknown or missing key otherwise (:func:`check_keys`)."""
    if set(data) != {table} or not isinstance(data[table], dict):
        raise ValueError(f"expected one table [{table}]")
    return check_keys(data[table], table, keys, optional)


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


#: An array of at most this many numbers is written on one line, however long its line.
SHORT_ARRAY = 5
#: Any other array is written on one line when ``key = [...]`` fits in this many characters.
LINE_CHARS = 100


def plain_toml_value(value, where: str):
    """``value`` as plain Python for a TOML writer: bool, int, float (NumPy's float64 and int64 become
    Python's), str, list (from a list or tuple) or dict; TypeError naming ``where`` and the value for anything
    else (None, a NumPy float32 or array), so nothing unreadable is ever written."""
    if isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, float):          # NumPy's float64 is one
        return float(value)
    if isinstance(value, (list, tuple)):
        return [plain_toml_value(v, f"{where}[{k}]") for k, v in enumerate(value)]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return {k: plain_toml_value(v, f"{where}.{k}" if where else k) for k, v in value.items()}
    raise TypeError(f"{where or 'value'}: cannot write {type(value).__name__} {value!r} to TOML "
                    "(bool, int, float, str, list or table)")


def toml_item(key: str, value):
    """A tomlkit item for a plain value (:func:`plain_toml_value`) under ``key``, laid out as psvs writes
    files (the module docstring): short arrays inline, long ones one item per line, tables as tables."""
    import tomlkit
    item = tomlkit.item(plain_toml_value(value, key))
    _lay_out(key, item, 0)
    return item


def _lay_out(key: str, item, indent: int) -> None:
    """Split every array under ``item`` that is neither short nor fits its line (``indent`` characters in)."""
    from tomlkit.items import AoT, Array, InlineTable, Table
    if isinstance(item, (Table, InlineTable)):
        for k, v in item.items():
            _lay_out(k, v, indent)
    elif isinstance(item, AoT):
        for table in item.body:
            _lay_out(key, table, indent)
    elif isinstance(item, Array):
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in item)
        line = indent + (len(f"{key} = ") if key else 0) + len(item.as_string())
        if not (numbers and len(item) <= SHORT_ARRAY) and line > LINE_CHARS:
            item.multiline(True)
            for v in item:
                _lay_out("", v, indent + 4)


def dumps_toml(data: dict) -> str:
    """TOML text of a nested dict of plain values (:func:`plain_toml_value`: NumPy float64 and int64 are
    written as Python's, anything else unwritable is a TypeError naming the key and the value), arrays laid
    out as the module docstring says.

    Examples
    --------
    >>> print(dumps_toml({"camera": {"focal_length_mm": 11.3, "image_size_px": [640, 480]}}), end="")
    [camera]
    focal_length_mm = 11.3
    image_size_px = [640, 480]
    """
    import tomlkit
    doc = tomlkit.document()
    for key, value in plain_toml_value(data, "").items():
        doc.add(key, toml_item(key, value))
    return tomlkit.dumps(doc)


def update_toml(text: str, data: dict, what: str = "TOML") -> str:
    """``text`` (a TOML file's) changed to hold exactly ``data`` (nested plain values), keeping its comments,
    key order and layout wherever a value is unchanged.

    A key whose value is equal (``==``, so ``100`` stays for ``100.0``) is left as written; a changed value is
    replaced in place, keeping its end-of-line comment at its column; keys and tables that ``data`` lacks are
    removed; new ones are appended to their table (new tables at the end) in :func:`toml_item`'s layout.
    ValueError("malformed <what>: ...") when ``text`` is not TOML (tomlkit refuses more than 100 levels of
    nesting itself).
    """
    import tomlkit
    from tomlkit.exceptions import ParseError
    try:
        doc = tomlkit.parse(text)
    except ParseError as exc:
        raise ValueError(f"malformed {what}: {exc}") from None
    _merge(doc, plain_toml_value(data, ""))
    return tomlkit.dumps(doc)


def _merge(container, data: dict) -> None:
    """Make a tomlkit table (or document) hold ``data``, changing only what differs (:func:`update_toml`).
    A table may be written as ``[a.b]``, inline (``b = {...}``), with dotted keys (``b.c = 1``) or out of
    order (``[a.b]`` after another table): each is a mapping here, merged where it stands."""
    for key in [k for k in container if k not in data]:
        del container[key]
    for key, value in data.items():
        old = container.get(key)
        if isinstance(value, dict) and isinstance(old, MutableMapping):
            _merge(old, value)
            continue
        if old is not None and not isinstance(old, MutableMapping) and _same(old.unwrap(), value):
            continue
        new = toml_item(key, value)
        if old is not None and not isinstance(old, MutableMapping) and old.trivia.comment:
            # tomlkit keeps the comment of a replaced value; keep it at its column too (a longer value
            # pushes it right, as far from the value as it was, up to 3 spaces)
            gap = len(old.trivia.comment_ws)
            new.trivia.comment_ws = " " * max(min(gap, 3), len(old.as_string()) + gap - len(new.as_string()), 1)
        container[key] = new


def _same(old, new) -> bool:
    """Equal values of the same kind (numbers by value, but never a bool for a number)."""
    if isinstance(old, dict) or isinstance(new, dict):
        return isinstance(old, dict) and isinstance(new, dict) and old.keys() == new.keys() and \
            all(_same(old[k], new[k]) for k in old)
    if isinstance(old, list) or isinstance(new, list):
        return isinstance(old, list) and isinstance(new, list) and len(old) == len(new) and \
            all(_same(a, b) for a, b in zip(old, new, strict=True))
    if isinstance(old, bool) or isinstance(new, bool):
        return type(old) is type(new) and old == new
    return old == new
