"""``target.toml``: the hand-held calibration target of a calibration folder (docs/calibration.md).

    [target]
    kind = "circle_grid"   # symmetric grid of dark discs on a light card
    rows = 4
    cols = 6
    spacing_mm = 14.0      # centre to centre
    diameter_mm = 7.0

``kind = "asymmetric_circle_grid"`` takes the same keys (OpenCV's asymmetric grid: ``rows`` rows of ``cols``
discs, rows ``spacing_mm`` apart, discs along a row twice that apart, odd rows shifted by ``spacing_mm``);
``kind = "charuco"`` takes ``squares_x``, ``squares_y``, ``square_mm``, ``marker_mm`` and ``dictionary``
(an OpenCV ArUco dictionary's name, e.g. "DICT_4X4_50").
"""
from __future__ import annotations

from psvs.io.schema import REQUIRED, Field, read_fields
from psvs.io.tomlfile import dumps_toml, load_table, parse_text, single_table
from psvs.simulate.textures import AsymmetricCircleGrid, CharucoBoard, CircleGrid

#: Most rows, columns or squares a side of a card (a printed card of 200 x 200 discs is no calibration target;
#: 1e9 rows asked 45 GiB before this bound).
MAX_COUNT = 200
_COUNT = Field("integer", high=MAX_COUNT, default=REQUIRED)
_MM = Field("number", note="mm", default=REQUIRED)
_GRID = {"rows": _COUNT, "cols": _COUNT, "spacing_mm": _MM, "diameter_mm": _MM}
#: The kinds of target and each one's keys (besides ``kind``), with their types (:mod:`psvs.io.schema`).
FIELDS = {
    "circle_grid": _GRID,
    "asymmetric_circle_grid": _GRID,
    "charuco": {"squares_x": _COUNT, "squares_y": _COUNT, "square_mm": _MM, "marker_mm": _MM,
                "dictionary": Field("string", note="an OpenCV ArUco dictionary's name", default=REQUIRED)},
}
KEYS = {kind: tuple(fields) for kind, fields in FIELDS.items()}
KINDS = tuple(KEYS)
_CLASSES = {"circle_grid": CircleGrid, "asymmetric_circle_grid": AsymmetricCircleGrid, "charuco": CharucoBoard}
_ALL = tuple(sorted({k for keys in KEYS.values() for k in keys}))


def load_target(path) -> CircleGrid | AsymmetricCircleGrid | CharucoBoard:
    """The target described by a ``target.toml``; ValueError naming the file and the key otherwise."""
    return load_table(path, "target", "target", ("kind",), optional=_ALL, parse=_target)


def target_from_text(text: str, where: str = "target file"):
    """The target described by a ``target.toml``'s text (e.g. chosen in the web page); ValueError naming
    ``where`` and the key otherwise, as :func:`load_target`'s name the file."""
    data = parse_text(text, where)
    try:
        return _target(single_table(data, "target", ("kind",), _ALL))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{where}: {exc}") from None


def _target(t: dict):
    kind = Field("string", choices=KINDS).value(t["kind"], "target.kind")
    args = read_fields({k: v for k, v in t.items() if k != "kind"}, "target", FIELDS[kind], what=kind)
    try:
        return _CLASSES[kind](**args)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"target.{exc}") from None


def dumps_target(target) -> str:
    """The ``target.toml`` text of a target (read back by :func:`load_target`)."""
    kind = next(k for k, cls in _CLASSES.items() if type(target) is cls)
    values = {k: float(getattr(target, k)) if k.endswith("_mm") else getattr(target, k) for k in KEYS[kind]}
    return dumps_toml({"target": {"kind": kind, **values}})
