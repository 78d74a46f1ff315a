"""Reading psvs's TOML files with errors that name the file."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path


def load_toml(path, what: str) -> dict:
    """Parse a TOML file (or JSON, by its suffix); raise FileNotFoundError("<what> file not found: ...")
    or ValueError("<path>: malformed TOML: ...")."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} file not found: {path}")
    text = path.read_text(encoding="utf-8")
    is_json = path.suffix.lower() == ".json"
    try:
        return json.loads(text) if is_json else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: malformed {'JSON' if is_json else 'TOML'}: {exc}") from None
