"""Rig files shipped with psvs, so a pip user has them: ``--rig default`` (or any name in :data:`SHIPPED`).

- ``default``: the paper's camera (f 11.3 mm, 640x480, 10 um pixels) and b = 100 mm, M1 at 22 mm, M2 at
  44 mm (a clear layout), unbounded mirrors.
- ``clear``: the same with the finite mirror sizes ``psvs design --rig-out`` gives.
- ``misaligned``: a build of ``clear`` with mirror tilts and shifts, a rotated box and a distorting lens.
- ``misaligned_knocked``: ``misaligned`` after a knock (M3 0.06 deg, M4 0.05/0.03 deg): what a drifted
  build's frames look like to ``psvs check`` and ``psvs refit``.
- ``mv1440``: a machine-vision camera (f 8 mm, 1440x1080, 3.45 um pixels, its lens's barrel distortion),
  b = 100 mm, a 2 mm BK7 plate splitting 45/55, M1 at 16 mm, M2 at 34.75 mm, the designed mirror sizes.
- ``mv1440_misaligned``: a build of ``mv1440`` with mirror tilts and shifts, a rotated box and the lens as
  it really is.

``examples/rigs/`` in the repository links to these files.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["SHIPPED", "shipped_rig_path"]

SHIPPED = ("default", "clear", "misaligned", "misaligned_knocked", "mv1440", "mv1440_misaligned")


def shipped_rig_path(name: str) -> Path:
    """Path of the shipped rig file ``name`` (one of :data:`SHIPPED`); ValueError naming the choices."""
    if name not in SHIPPED:
        raise ValueError(f"no shipped rig {name!r} (shipped: {', '.join(SHIPPED)})")
    return Path(str(resources.files(__name__).joinpath(f"{name}.toml")))
