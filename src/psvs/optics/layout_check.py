"""Is a rig's layout one a build can have? Asked by every command that measures through a rig, answered
once per rig content.

:func:`check_clear` designs the rig's mirrors (:func:`psvs.optics.design.design_mirrors`: the camera's whole
field traced through both paths, every mirror and the plate checked for obstructions and collisions), which
takes about half a second on a 1440 x 1080 camera (much of it Numba's start-up, which a later kernel would
pay anyway) and loads the mesh library, on every call. A clear verdict depends only on the rig's camera and
mirror values and on the optics code, so it is kept:

- in memory, for the process (``psvs batch``, ``live``, ``serve``);
- on disk, as an empty file named by its key in ``layout/`` of the user's cache folder
  (:func:`psvs._cache.cache_dir`): the key (:func:`layout_key`) hashes every value of the camera and mirrors
  and the source of ``psvs/optics``, so a changed rig, or a new psvs, is checked again.

Only a clear verdict (a build can have the layout; one that vignettes less than half of each view included) is
kept: a blocked layout is designed again, to name its problems.
"""
from __future__ import annotations

import contextlib

from psvs._cache import cache_dir, content_key
from psvs.errors import RigGeometryError
from psvs.optics.rig import Rig

#: The code whose source is part of the key: the ray tracing and the design that decide the verdict.
_CODE = ("optics/*.py",)
#: The keys of the rigs found clear in this process.
_CLEAR: set[str] = set()


def layout_key(rig: Rig) -> str:
    """The key (64 hex digits) of a rig's layout verdict: its camera's and mirrors' values exactly (not its
    file's path, nor its calibration record) and the optics code's source."""
    return content_key({"verdict": "layout clear", "camera": rig.camera, "mirrors": rig.mirrors}, _CODE)


def check_clear(rig: Rig, name: str = "the rig") -> Rig:
    """``rig`` itself when a build can have its layout (:attr:`~psvs.optics.design.MirrorDesign.buildable`:
    clear, or vignetting at most half of each view's image, as a build whose glass meets another beam at a
    corner does; it measures in the rest) and its mirrors as sized in it lose at most as much
    (:func:`psvs.optics.obstruction.sized_shares`), else :class:`~psvs.errors.RigGeometryError` saying how much of each
    view is lost and naming the first problem: nothing measured or exported through such a layout describes a
    build.
    ``name`` says which rig (a file's name) in the message. A rig of the same values found clear before (in
    this process or the cache folder) is not designed again."""
    key = layout_key(rig)
    marker = _marker(key)
    if key in _CLEAR or (marker is not None and marker.is_file()):
        _CLEAR.add(key)
        return rig
    from psvs.optics.design import MAX_BLOCKED_SHARE, design_mirrors, share_words  # only for a rig not yet known
    from psvs.optics.obstruction import sized_shares
    d = design_mirrors(rig, search=False)
    limit = f"(more than {100 * MAX_BLOCKED_SHARE:.0f} % is no build)"
    if not d.buildable:
        more = f" (and {len(d.problems) - 1} more)" if len(d.problems) > 1 else ""
        raise RigGeometryError(f"{name} is no layout a build can have: {d.share_words()} {limit}: "
                               f"{d.problems[0]}{more}; `psvs design` shows its layout")
    own = sized_shares(rig)
    if max(own.values()) > MAX_BLOCKED_SHARE:
        raise RigGeometryError(f"{name}'s mirrors, as sized in it, are too small for the camera's field: "
                               f"{share_words(own)} {limit}; `psvs design` sizes them")
    _CLEAR.add(key)
    if marker is not None:
        with contextlib.suppress(OSError):      # a folder that cannot be written: no disk cache, no error
            marker.parent.mkdir(parents=True, exist_ok=True)
            marker.touch()
    return rig


def forget() -> None:
    """Forget the verdicts of this process (the cache folder's stay)."""
    _CLEAR.clear()


def _marker(key: str):
    folder = cache_dir()
    return None if folder is None else folder / "layout" / f"{key}.clear"
