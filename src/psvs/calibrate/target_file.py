"""``target.toml``: the hand-held calibration target of a calibration folder (docs/calibration.md).

    [target]
    kind = "circle_grid"   # symmetric grid of dark discs on a light card
    rows = 4
    cols = 6
    spacing_mm = 14.0      # centre to centre
    diameter_mm = 7.0
"""
from __future__ import annotations

from psvs.io.tomlfile import dumps_toml, load_table
from psvs.simulate.textures import CircleGrid

KINDS = ("circle_grid",)
_KEYS = ("kind", "rows", "cols", "spacing_mm", "diameter_mm")


def load_target(path) -> CircleGrid:
    """The target described by a ``target.toml``; ValueError naming the file and the key otherwise."""
    return load_table(path, "target", "target", _KEYS, parse=_target)


def _target(t: dict) -> CircleGrid:
    if t["kind"] not in KINDS:
        raise ValueError(f"target.kind must be one of {', '.join(KINDS)}, got {t['kind']!r}")
    for k in ("spacing_mm", "diameter_mm"):
        if isinstance(t[k], bool) or not isinstance(t[k], (int, float)):
            raise ValueError(f"target.{k} must be a number (mm), got {t[k]!r}")
    try:
        return CircleGrid(rows=t["rows"], cols=t["cols"], spacing_mm=float(t["spacing_mm"]),
                          diameter_mm=float(t["diameter_mm"]))
    except ValueError as exc:
        raise ValueError(f"target.{exc}") from None


def dumps_target(grid: CircleGrid) -> str:
    """The ``target.toml`` text of a circle grid (read back by :func:`load_target`)."""
    return dumps_toml({"target": {"kind": "circle_grid", "rows": grid.rows, "cols": grid.cols,
                                  "spacing_mm": float(grid.spacing_mm), "diameter_mm": float(grid.diameter_mm)}})
