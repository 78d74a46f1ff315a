"""The user's psvs cache folder and the content keys of what is kept in it.

What psvs computes once per rig and keeps across processes (a build's rectification and depth table,
:mod:`psvs.dense.rig_cache`; the verdict that a rig's layout is clear, :mod:`psvs.optics.layout_check`) is
named by a key made from the *values* it was computed from and the source of the code that computed them,
never from a file's path: a rig file whose values change, or a new version of psvs, never reads an older
entry.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

#: Where the cache folder is, when set (else XDG_CACHE_HOME/psvs, else ~/.cache/psvs).
ENV_VAR = "PSVS_CACHE_DIR"
_ROOT = Path(__file__).resolve().parent


def cache_dir() -> Path | None:
    """The user's psvs cache folder: ``$PSVS_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/psvs`` (an absolute
    path), else ``~/.cache/psvs``; None when no home folder is known. It may not exist yet."""
    own = os.environ.get(ENV_VAR, "")
    if own:
        return Path(own).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    if xdg and Path(xdg).is_absolute():
        return Path(xdg) / "psvs"
    try:
        return Path.home() / ".cache" / "psvs"
    except RuntimeError:      # no home folder
        return None


def canon(x):
    """A JSON-able form of a value that two different values never share: dataclasses field by field with
    their type's name, numbers as exact float hex, sequences as lists."""
    if dataclasses.is_dataclass(x):
        return [type(x).__name__, {f.name: canon(getattr(x, f.name)) for f in dataclasses.fields(x)}]
    if isinstance(x, (bool, str)) or x is None:
        return x
    if isinstance(x, (int, float, np.integer, np.floating)):
        return float(x).hex()
    if isinstance(x, (tuple, list)):
        return [canon(v) for v in x]
    raise TypeError(f"cannot key a value of type {type(x).__name__}")


@lru_cache(maxsize=None)
def code_digest(patterns: tuple[str, ...]) -> str:
    """SHA-256 (hex) of the source of psvs's modules matching ``patterns`` (globs relative to the package,
    e.g. ``"optics/*.py"``); a file that cannot be read (a frozen install) counts by its name."""
    h = hashlib.sha256()
    for pattern in patterns:
        for path in sorted(_ROOT.glob(pattern)):
            h.update(path.relative_to(_ROOT).as_posix().encode())
            try:
                h.update(path.read_bytes())
            except OSError:
                h.update(b"?")
    return h.hexdigest()


def content_key(values: dict, code: tuple[str, ...]) -> str:
    """The cache key (64 hex digits) of ``values`` (a dict of what an entry was computed from, each made
    exact by :func:`canon`) and of the code that computes it (:func:`code_digest` of ``code``)."""
    text = json.dumps({"code": code_digest(tuple(code)), **{k: canon(v) for k, v in values.items()}},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()
