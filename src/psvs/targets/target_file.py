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

from psvs.io.tomlfile import check_keys, dumps_toml, load_table
from psvs.simulate.textures import AsymmetricCircleGrid, CharucoBoard, CircleGrid

#: The kinds of target and each one's keys (besides ``kind``).
KEYS = {
    "circle_grid": ("rows", "cols", "spacing_mm", "diameter_mm"),
    "asymmetric_circle_grid": ("rows", "cols", "spacing_mm", "diameter_mm"),
    "charuco": ("squares_x", "squares_y", "square_mm", "marker_mm", "dictionary"),
}
KINDS = tuple(KEYS)
_CLASSES = {"circle_grid": CircleGrid, "asymmetric_circle_grid": AsymmetricCircleGrid, "charuco": CharucoBoard}
_ALL = tuple(sorted({k for keys in KEYS.values() for k in keys}))


def load_target(path) -> CircleGrid | AsymmetricCircleGrid | CharucoBoard:
    """The target described by a ``target.toml``; ValueError naming the file and the key otherwise."""
    return load_table(path, "target", "target", ("kind",), optional=_ALL, parse=_target)


def _target(t: dict):
    kind = t["kind"]
    if kind not in KEYS:
        raise ValueError(f"target.kind must be one of {', '.join(KINDS)}, got {kind!r}")
    check_keys(t, "target", KEYS[kind], ("kind",), what=kind)
    for k in KEYS[kind]:
        if k.endswith("_mm") and (isinstance(t[k], bool) or not isinstance(t[k], (int, float))):
            raise ValueError(f"target.{k} must be a number (mm), got {t[k]!r}")
        if k == "dictionary" and not isinstance(t[k], str):
            raise ValueError(f"target.dictionary must be a string (an OpenCV ArUco dictionary), got {t[k]!r}")
    args = {k: float(t[k]) if k.endswith("_mm") else t[k] for k in KEYS[kind]}
    try:
        return _CLASSES[kind](**args)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"target.{exc}") from None


def dumps_target(target) -> str:
    """The ``target.toml`` text of a target (read back by :func:`load_target`)."""
    kind = next(k for k, cls in _CLASSES.items() if type(target) is cls)
    values = {k: float(getattr(target, k)) if k.endswith("_mm") else getattr(target, k) for k in KEYS[kind]}
    return dumps_toml({"target": {"kind": kind, **values}})
