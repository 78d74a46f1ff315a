"""Example files shipped with psvs, so a pip user has what the README's commands read: ``psvs examples -o DIR``
writes them out (``examples/`` in the repository links to these files).

- ``matches.csv``: five correspondences (u_l, v_l, u_r, v_r px) through the ``clear`` rig, with their truth
  in ``matches_truth.csv`` (X, Y, Z mm); ``known_points.csv``: matches with known depths, for
  ``psvs fit-refraction``.
- ``scenes/desk.toml`` (with its image and mesh in ``scenes/assets/``) and ``scenes/pattern.toml``: scene
  files (docs/scene_file.md).
- ``tolerances_small.toml``: a small Monte-Carlo tolerance study (docs/tolerancing.md).
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["example_files"]


def example_files() -> dict[str, Path]:
    """The shipped example files: their paths relative to the examples folder (posix, e.g.
    ``"scenes/assets/label.png"``) -> where they are installed."""
    root = Path(str(resources.files(__name__)))
    return {p.relative_to(root).as_posix(): p for p in sorted(root.rglob("*"))
            if p.is_file() and p.suffix in {".csv", ".toml", ".png", ".stl"}}
