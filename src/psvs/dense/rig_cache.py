"""A build's rectification, its remaps and its depth table, made once per rig content: kept in memory for the
process and in the user's cache folder across processes.

Fitting a build's dual rectification (:func:`psvs.optics.rectify.rectify`), its two remaps
(:meth:`~psvs.optics.rectify.Rectification.maps`), the remaps' fill-in (:func:`nearest_inside`) and the depth
table (:mod:`psvs.dense.depth_table`) takes a few seconds for a 1440 × 1080 camera, and every new process
(a ``psvs disparity`` call) paid it again. Here they are made once per *rig content* and working range:

- **in memory**: :func:`rectification` returns the object :func:`~psvs.optics.rectify.rectify` keeps (the
  last few rigs and ranges), and the fill-in and the depth table live as long as it does, so ``psvs batch``,
  ``live`` and ``serve`` pay once per rig;
- **on disk**, in :func:`cache_dir` (``$PSVS_CACHE_DIR``, else ``$XDG_CACHE_HOME/psvs``, else
  ``~/.cache/psvs``), under ``builds/``: one file for the rectification with its remaps and fill-in, one for
  the depth table, both named by :func:`rig_key`, a hash of every value of the rig's camera and mirrors
  (not of its file's path or the calibration record), of the working range, of this module's
  :data:`FORMAT_VERSION` and of the source of the code that computes them. A rig file whose values change
  therefore never reads an older entry, and neither does a new version of psvs.

A file is written atomically (:func:`psvs.io.atomic.write_atomic`), an uncompressed NumPy ``.npz`` whose
members each carry the zip format's CRC-32, checked as each is read to its end (:func:`_members`; a SHA-256 of
the arrays on top of it took a quarter of the 0.12 s a 1440 x 1080 build's 28 MB file took to read); one that
is no regular file, cannot be read, is truncated, damaged, of another format, or holds values of another fit
is ignored, recomputed and rewritten.
A folder that cannot be made or written means no disk cache, never an error. The folder keeps the
:data:`KEEP_FILES` files used last.
"""
from __future__ import annotations

import contextlib
import io
import os
import stat
import threading
import weakref
import zipfile
from pathlib import Path

import numpy as np

from psvs._cache import cache_dir, content_key
from psvs.dense.depth_table import DepthTable, build_depth_table, node_counts
from psvs.io.atomic import write_atomic
from psvs.optics.rectify import VIEWS, Rectification, needs_rectification, rectify, remember, remembered
from psvs.optics.rectify import forget as forget_fits
from psvs.optics.rig import Rig

#: The files' layout; a change of it (or of what they hold) takes a new number.
FORMAT_VERSION = 1
#: Files kept in the cache folder (the least recently used beyond it are removed).
KEEP_FILES = 24

#: The fitted values of a rectification, as stored.
_FIT = ("rotation", "camera_matrix", "centres_mm", "z_ref_mm", "size_px", "residual_px")
#: The modules whose code decides what is stored (their source is part of the key).
_CODE = ("optics/*.py", "measure/triangulate.py", "dense/depth_table.py", "dense/rig_cache.py")

_READY: weakref.WeakSet = weakref.WeakSet()                    # rectifications with their remaps in place
_NEAREST: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()   # rect -> {view: (H', W') int32}
_FILLED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()    # rect -> {view: (map_u, map_v)}
_OUTSIDE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()   # rect -> {view: flat indices}
_TABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()    # rect -> DepthTable
_LOCKS: dict[str, threading.Lock] = {}
_LOCKS_LOCK = threading.Lock()


def rig_key(rig: Rig, near_mm: float, far_mm: float) -> str:
    """The cache key (64 hex digits) of a rig's optics over a working range: a SHA-256 of every value of
    its camera and mirrors (floats exactly, by their hex form), near_mm and far_mm, :data:`FORMAT_VERSION`
    and the source of the code that computes the cached values (:func:`psvs._cache.content_key`)."""
    return content_key({"format": FORMAT_VERSION, "camera": rig.camera, "mirrors": rig.mirrors,
                        "near_mm": float(near_mm), "far_mm": float(far_mm)}, _CODE)


def rectification(rig: Rig, near_mm: float = 400.0, far_mm: float = 1200.0) -> Rectification | None:
    """The rig's dual rectification over near..far mm with its two remaps in place (None on the paper's
    geometry, where the complex image's own rows serve: :func:`psvs.optics.rectify.needs_rectification`):
    the one :func:`psvs.optics.rectify.rectify` keeps in memory, else the one in the cache folder, else
    fitted now (and stored). The same object as ``rectify(rig, near_mm, far_mm)`` from then on."""
    if not needs_rectification(rig):
        return None
    near_mm, far_mm = float(near_mm), float(far_mm)
    rect = remembered(rig, near_mm, far_mm)
    if rect is not None and rect in _READY:
        return rect
    if not 0 < near_mm < far_mm:
        raise ValueError(f"working range must satisfy 0 < near < far, got near={near_mm!r}, far={far_mm!r}")
    key = rig_key(rig, near_mm, far_mm)
    with _lock(key):
        rect = remembered(rig, near_mm, far_mm)
        if rect is not None and rect in _READY:
            return rect
        path = _path(key, "rect")
        stored = _read(path, key) if path is not None else None
        if stored is not None and not _rect_entry_ok(stored):
            stored = None
        if rect is None and stored is not None:
            rect = remember(_rect_from(stored, rig, near_mm, far_mm))
        if rect is None:
            rect = rectify(rig, near_mm, far_mm)
        if stored is not None and _same_fit(stored, rect):
            _adopt(rect, stored)
        else:
            _write(path, key, {**_fit_arrays(rect), **_table_arrays(rect)})
        _READY.add(rect)
    return rect


def nearest_inside(rect: Rectification, view: str) -> np.ndarray:
    """For every pixel of a view's rectified grid, the flat index (into an (H', W') image) of the nearest
    pixel inside the view's field (itself when inside): (H', W') int32, read-only. A rectified image
    ``a.ravel()[index]`` repeats the field's edge outside it (no artificial edge for matching)."""
    per_rect = _NEAREST.setdefault(rect, {})
    if view not in per_rect:
        outside = rect.maps(view)[0] < 0
        h, w = outside.shape
        if outside.any():
            from scipy.ndimage import distance_transform_edt  # a cached rig does not need scipy.ndimage
            _, (iv, iu) = distance_transform_edt(outside, return_indices=True)
            index = (iv * w + iu).astype(np.int32)
        else:
            index = np.arange(h * w, dtype=np.int32).reshape(h, w)
        index.setflags(write=False)
        per_rect[view] = index
    return per_rect[view]


def outside_pixels(rect: Rectification, view: str) -> np.ndarray:
    """The flat indices (into an (H', W') map, int64, read-only) of a view's rectified grid's pixels outside
    its field: where a map of that view has no answer."""
    per_rect = _OUTSIDE.setdefault(rect, {})
    if view not in per_rect:
        index = np.flatnonzero(rect.maps(view)[0] < 0)
        index.setflags(write=False)
        per_rect[view] = index
    return per_rect[view]


def filled_maps(rect: Rectification, view: str) -> tuple[np.ndarray, np.ndarray]:
    """A view's cv2.remap maps (float32 (H', W'), read-only) with every pixel outside its field sampling where
    its :func:`nearest_inside` pixel samples: ``cv2.remap`` through them is the rectified image with the
    field's edge repeated outside it (:func:`psvs.dense.build.rectified_images`), and a band of their rows
    resamples only that band of it."""
    per_rect = _FILLED.setdefault(rect, {})
    if view not in per_rect:
        outside = outside_pixels(rect, view)          # inside the field, each pixel its own nearest
        source = nearest_inside(rect, view).ravel()[outside]
        out = []
        for m in rect.maps(view):
            filled = np.array(m, np.float32, order="C")
            filled.ravel()[outside] = m.ravel()[source]
            filled.setflags(write=False)
            out.append(filled)
        per_rect[view] = tuple(out)
    return per_rect[view]


def depth_table(rect: Rectification) -> DepthTable:
    """The depth table of a build's rectification (:func:`psvs.dense.depth_table.build_depth_table`): kept
    in memory as long as ``rect`` lives, read from the cache folder, else built now (and stored)."""
    table = _TABLES.get(rect)
    if table is not None:
        return table
    key = rig_key(rect.rig, rect.near_mm, rect.far_mm)
    with _lock(key):
        table = _TABLES.get(rect)
        if table is not None:
            return table
        path = _path(key, "depth")
        stored = _read(path, key) if path is not None else None
        table = _table_from(stored, rect) if stored is not None and _same_fit(stored, rect) else None
        if table is None:
            table = build_depth_table(rect)
            _write(path, key, {**_fit_arrays(rect), **_depth_arrays(table)})
        _TABLES[rect] = table
    return table


def forget() -> None:
    """Empty this module's memory and :func:`psvs.optics.rectify.rectify`'s (the disk cache stays): the next
    call reads the folder or computes."""
    forget_fits()
    _READY.clear()
    for per_rect in (_NEAREST, _FILLED, _OUTSIDE, _TABLES):
        per_rect.clear()


def _lock(key: str) -> threading.Lock:
    """One lock per key: two threads asking for the same rig compute it once."""
    with _LOCKS_LOCK:
        return _LOCKS.setdefault(key, threading.Lock())


def _path(key: str, kind: str) -> Path | None:
    folder = cache_dir()
    return None if folder is None else folder / "builds" / f"{key}.{kind}.npz"


# ---- what a file holds -------------------------------------------------------------------------------------

def _fit_arrays(rect: Rectification) -> dict:
    return {"rotation": np.asarray(rect.rotation, np.float64),
            "camera_matrix": np.asarray(rect.camera_matrix, np.float64),
            "centres_mm": np.stack([rect.centres_mm[v] for v in VIEWS]).astype(np.float64),
            "z_ref_mm": np.float64(rect.z_ref_mm), "size_px": np.asarray(rect.size_px, np.int64),
            "residual_px": np.float64(rect.residual_px)}


def _same_fit(stored: dict, rect: Rectification) -> bool:
    """True when ``stored`` holds exactly ``rect``'s fitted values."""
    fit = _fit_arrays(rect)
    return all(k in stored and stored[k].shape == fit[k].shape and np.array_equal(stored[k], fit[k]) for k in _FIT)


def _rect_from(stored: dict, rig: Rig, near_mm: float, far_mm: float) -> Rectification:
    c = stored["centres_mm"]
    w, h = (int(s) for s in stored["size_px"])
    return Rectification(rig, stored["rotation"].copy(), stored["camera_matrix"].copy(),
                         {"left": c[0].copy(), "right": c[1].copy()}, float(stored["z_ref_mm"]), (w, h),
                         float(stored["residual_px"]), near_mm, far_mm)


def _table_arrays(rect: Rectification) -> dict:
    """The remaps of both views and their fill-in (only the outside pixels' entries: the rest is the
    identity)."""
    out = {}
    for view in VIEWS:
        mu, mv = rect.maps(view)
        index = nearest_inside(rect, view).ravel()
        moved = np.flatnonzero(index != np.arange(index.size)).astype(np.int32)
        out.update({f"map_u_{view}": mu, f"map_v_{view}": mv, f"moved_{view}": moved,
                    f"nearest_{view}": index[moved]})
    return out


def _rect_entry_ok(stored: dict) -> bool:
    """The shapes and index ranges a rectification's file must have (the members' CRC-32 has vouched for the bytes)."""
    try:
        w, h = (int(s) for s in stored["size_px"])
        shapes = {"rotation": (3, 3), "camera_matrix": (3, 3), "centres_mm": (2, 3), "z_ref_mm": (),
                  "residual_px": (), "size_px": (2,)}
        if any(stored[k].shape != s for k, s in shapes.items()):
            return False
        for view in VIEWS:
            maps = (stored[f"map_u_{view}"], stored[f"map_v_{view}"])
            if any(m.dtype != np.float32 or m.shape != (h, w) for m in maps):
                return False
            moved, src = stored[f"moved_{view}"], stored[f"nearest_{view}"]
            if moved.dtype != np.int32 or src.dtype != np.int32 or moved.shape != src.shape or moved.ndim != 1:
                return False
            if len(moved) and (min(moved.min(), src.min()) < 0 or max(moved.max(), src.max()) >= w * h):
                return False
        return True
    except (KeyError, TypeError, ValueError):
        return False


def _adopt(rect: Rectification, stored: dict) -> None:
    """Put a file's remaps and fill-in in place on ``rect`` (whose fit they were made from)."""
    w, h = rect.size_px
    per_rect = _NEAREST.setdefault(rect, {})
    for view in VIEWS:
        rect.preload_maps(view, stored[f"map_u_{view}"], stored[f"map_v_{view}"])
        index = np.arange(w * h, dtype=np.int32)
        index[stored[f"moved_{view}"]] = stored[f"nearest_{view}"]
        index = index.reshape(h, w)
        index.setflags(write=False)
        per_rect[view] = index


def _depth_arrays(table: DepthTable) -> dict:
    return {"step_px": np.int64(table.step_px), "slopes": table.slopes, "cells_left": table.cells_left,
            "cells_right": table.cells_right, "disparity_px": np.asarray(table.disparity_px, np.float64),
            "max_error_mm": np.float64(table.max_error_mm)}


def _table_from(stored: dict, rect: Rectification) -> DepthTable | None:
    """The depth table a file holds, or None when its arrays do not fit ``rect``'s grid."""
    try:
        step = int(stored["step_px"])
        nu, nv = node_counts(rect.size_px, step)
        slopes, cells = stored["slopes"], (stored["cells_left"], stored["cells_right"])
        d = stored["disparity_px"]
        if (step < 1 or slopes.dtype != np.float64 or slopes.shape != (nv, nu, 2) or d.shape != (2,)
                or any(c.dtype != bool or c.shape != (nv - 1, nu - 1) for c in cells)):
            return None
        return DepthTable(step, slopes, cells[0], cells[1], (float(d[0]), float(d[1])),
                          float(stored["max_error_mm"]))
    except (KeyError, TypeError, ValueError):
        return None


# ---- files ---------------------------------------------------------------------------------------------

def _write(path: Path | None, key: str, arrays: dict) -> None:
    """Store ``arrays`` at ``path``, atomically; nothing when the folder cannot be written."""
    if path is None:
        return
    buf = io.BytesIO()
    np.savez(buf, format=np.int64(FORMAT_VERSION), key=np.str_(key), **arrays)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, buf.getvalue(), batch=False)
    except OSError:     # a read-only or full disk, a file in the folder's place: no disk cache
        return
    _prune(path.parent)


def _read(path: Path, key: str) -> dict | None:
    """The arrays stored at ``path`` for ``key``, or None when there is no such regular file or it cannot be
    trusted (unreadable, truncated, damaged: a member whose CRC-32 does not match, of another format or key)."""
    try:
        if not stat.S_ISREG(path.stat().st_mode):     # a pipe there would block the read
            return None
        arrays = _members(path)
        head = {name: arrays.pop(name) for name in ("format", "key")}
        if int(head["format"]) != FORMAT_VERSION or str(head["key"]) != key:
            return None
    except Exception:   # noqa: BLE001 - whatever a missing or damaged file raises (OS, zip, npy header, value)
        return None
    with contextlib.suppress(OSError):
        os.utime(path)       # recently used: kept by _prune
    return arrays


def _members(path: Path) -> dict:
    """Every array of the ``.npz`` at ``path``, each member read to its end, so that the zip's CRC-32 of the
    whole member (its ``.npy`` header too) is checked: ``np.load`` stops after the array's bytes, and a flipped
    bit in a header's length field shifted an array by an element unchecked (an adversarial trial: every depth
    19 mm off, exit 0, and the damaged file kept). ValueError when a member holds more than its array."""
    out = {}
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            with zf.open(info) as fp:
                out[info.filename.removesuffix(".npy")] = np.lib.format.read_array(fp, allow_pickle=False)
                if fp.read(1):                         # reads to the end: zipfile checks the CRC-32 there
                    raise ValueError(f"{info.filename} holds more than its array")
    return out


def _prune(folder: Path) -> None:
    """Remove the least recently used files beyond :data:`KEEP_FILES`."""
    try:
        files = sorted(folder.glob("*.npz"), key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError:     # a file removed meanwhile by another process
        return
    for old in files[KEEP_FILES:]:
        with contextlib.suppress(OSError):     # removed meanwhile by another process
            old.unlink()
