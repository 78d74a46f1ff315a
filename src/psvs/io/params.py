"""Rig files (TOML or JSON) <-> :class:`~psvs.optics.rig.Rig`.

Format (docs/rig_file.md). Required: ``[camera] focal_length_mm, pixel_pitch_mm, image_size_px`` and
``[mirrors] baseline_mm, m1_axis_distance_mm, m2_axis_distance_mm, plate_thickness_mm, refractive_index``.
Optional: ``principal_point_px`` (image centre), ``distortion`` ([k1, k2, p1, p2, k3], OpenCV's order; the
older ``distortion_k = [k1, k2]`` still loads), ``relative_illumination`` ([a2, a4], the lens's fall-off:
:mod:`psvs.optics.illumination`; flat when absent), ``angle_deg`` (45), ``split_ratio`` (0.5),
``refraction_l_mm`` / ``refraction_m_mm`` (derived from d, n, omega_1), ``box_rotation_deg`` ([0, 0, 0]), and
per-mirror tables ``[mirrors.m1]`` .. ``[mirrors.m4]`` with an extent (``along_mm = [min, max]`` and
``height_mm = [min, max]``, unbounded when absent) and the build's pose error (``tilt_deg = [a, b]``,
``shift_mm``; zero when absent). Unknown keys are errors: a misspelt key must not fall back to a default.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from psvs.io.atomic import write_atomic
from psvs.io.schema import check_keys
from psvs.io.text import read_text
from psvs.io.tomlfile import dumps_toml, load_toml, parse_text, update_toml
from psvs.optics.bounds import check_rig_bounds
from psvs.optics.rig import MIRROR_NAMES, Calibration, Camera, MirrorError, MirrorExtent, Mirrors, Rig
from psvs.rigs import SHIPPED, shipped_rig_path

_CAMERA_REQUIRED = ("focal_length_mm", "pixel_pitch_mm", "image_size_px")
_CAMERA_OPTIONAL = ("principal_point_px", "distortion", "distortion_k", "relative_illumination")
_MIRRORS_REQUIRED = ("baseline_mm", "m1_axis_distance_mm", "m2_axis_distance_mm",
                     "plate_thickness_mm", "refractive_index")
_MIRRORS_OPTIONAL = ("angle_deg", "split_ratio", "refraction_l_mm", "refraction_m_mm", "box_rotation_deg")
_EXTENT_KEYS = ("along_mm", "height_mm")
_ERROR_KEYS = ("tilt_deg", "shift_mm")


def rig_path(path) -> Path:
    """The file a ``--rig`` argument names: the path itself, or, when no such file exists and it is a bare
    name, the rig shipped with psvs under that name (``default``, ``clear``, ``misaligned``: :mod:`psvs.rigs`)."""
    path = Path(path)
    if not path.exists() and not path.suffix and path.name == str(path):
        if path.name not in SHIPPED:
            raise FileNotFoundError(f"rig file not found: {path} (shipped rigs: {', '.join(SHIPPED)})")
        return shipped_rig_path(path.name)
    return path


def load_rig(path) -> Rig:
    """Read a rig file (``.toml`` or ``.json``), or a shipped rig by its name (:func:`rig_path`); errors name
    the file and the key."""
    path = rig_path(path)
    data = load_toml(path, "rig")
    try:
        return rig_from_dict(data)
    except (ValueError, TypeError) as exc:
        raise type(exc)(f"{path}: {exc}") from None


def rig_from_text(text: str, where: str = "rig file") -> Rig:
    """A rig from the TOML text of a rig file (as ``psvs calibrate`` writes it, e.g. uploaded to the web
    page); errors name ``where`` and the key, as :func:`load_rig`'s name the file."""
    data = parse_text(text, where)
    try:
        return rig_from_dict(data)
    except (ValueError, TypeError) as exc:
        raise type(exc)(f"{where}: {exc}") from None


def _table(data: dict, name: str) -> dict:
    if name not in data:
        raise ValueError(f"missing table [{name}]")
    t = data[name]
    if not isinstance(t, dict):
        raise ValueError(f"[{name}] must be a table, got {type(t).__name__}")
    return t


def _pair(value, where: str):
    return _numbers(value, where, 2)


_COUNT = {2: "two", 3: "three", 5: "five"}


def _numbers(value, where: str, n: int) -> tuple:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise ValueError(f"{where} must be a list of {_COUNT[n]} numbers, got {value!r}")
    return tuple(value)


def _degrees_to_rad(values: tuple, where: str) -> tuple:
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise TypeError(f"{where} must hold numbers (degrees), got {type(v).__name__} {v!r}")
    out = tuple(math.radians(v) for v in values)
    if not all(math.isfinite(v) for v in out):
        raise ValueError(f"{where} must be finite degrees, got {list(values)!r}")
    return out


def _deg_out(rad: float) -> float:
    """Degrees for a file: 12 significant digits, so that a file read and written again is unchanged."""
    return float(f"{math.degrees(rad):.12g}")


def rig_from_dict(data: dict) -> Rig:
    """Build a :class:`Rig` from the nested dict of a rig file (degrees converted to radians); a value
    outside what real hardware has is refused (:mod:`psvs.optics.bounds`)."""
    if not isinstance(data, dict):
        raise ValueError(f"a rig file must hold tables [camera] and [mirrors], got {type(data).__name__}")
    unknown = sorted(set(data) - {"camera", "mirrors", "calibration"})
    if unknown:
        raise ValueError(f"unknown table [{unknown[0]}] (allowed: [camera], [mirrors], [calibration])")
    calibration = None
    if "calibration" in data:
        cal_t = _table(data, "calibration")
        check_keys(cal_t, "calibration", ("rms_px", "rms_left_px", "rms_right_px", "images"), ("kinds",))
        calibration = _build(Calibration, "calibration", **cal_t)
    cam_t, mir_t = _table(data, "camera"), _table(data, "mirrors")
    cam_t = {k: v for k, v in cam_t.items() if k != "acquisition"}   # the camera's settings: psvs.io.acquisition
    check_keys(cam_t, "camera", _CAMERA_REQUIRED, _CAMERA_OPTIONAL)
    scalars = {k: v for k, v in mir_t.items() if k not in MIRROR_NAMES}
    check_keys(scalars, "mirrors", _MIRRORS_REQUIRED, _MIRRORS_OPTIONAL)

    size = _pair(cam_t["image_size_px"], "camera.image_size_px")
    if "principal_point_px" in cam_t:
        cpp = _pair(cam_t["principal_point_px"], "camera.principal_point_px")
    elif all(isinstance(s, int) for s in size):
        cpp = ((size[0] - 1) / 2, (size[1] - 1) / 2)
    else:
        cpp = (0.0, 0.0)  # Camera() rejects the size with its own message
    if "distortion" in cam_t and "distortion_k" in cam_t:
        raise ValueError("camera.distortion and camera.distortion_k are both given: keep distortion "
                         "([k1, k2, p1, p2, k3])")
    if "distortion_k" in cam_t:
        dist = (*_pair(cam_t["distortion_k"], "camera.distortion_k"), 0.0, 0.0, 0.0)
    else:
        dist = _numbers(cam_t.get("distortion", [0.0] * 5), "camera.distortion", 5)
    ri = _numbers(cam_t.get("relative_illumination", [0.0, 0.0]), "camera.relative_illumination", 2)
    camera = _build(Camera, "camera", focal_length_mm=cam_t["focal_length_mm"],
                    pixel_pitch_mm=_pair(cam_t["pixel_pitch_mm"], "camera.pixel_pitch_mm"),
                    image_size_px=size, principal_point_px=cpp, distortion=dist, relative_illumination=ri)

    kwargs = {k: scalars[k] for k in _MIRRORS_REQUIRED}
    for k in ("split_ratio", "refraction_l_mm", "refraction_m_mm"):
        if k in scalars:
            kwargs[k] = scalars[k]
    if "angle_deg" in scalars:
        ang = scalars["angle_deg"]
        if isinstance(ang, bool) or not isinstance(ang, (int, float)):
            raise TypeError(f"mirrors.angle_deg must be a number, got {type(ang).__name__} {ang!r}")
        if not 0 < ang < 90:   # checked here, in the file's degrees (the model checks radians)
            raise ValueError(f"mirrors.angle_deg must be in (0, 90) degrees, got {ang!r}")
        kwargs["angle_rad"] = math.radians(ang)
    if "box_rotation_deg" in scalars:
        kwargs["box_rotation_rad"] = _degrees_to_rad(
            _numbers(scalars["box_rotation_deg"], "mirrors.box_rotation_deg", 3), "mirrors.box_rotation_deg")
    for name in MIRROR_NAMES:
        if name in mir_t:
            tab = mir_t[name]
            where = f"mirrors.{name}"
            check_keys(tab, where, (), _EXTENT_KEYS + _ERROR_KEYS)
            given = [k for k in _EXTENT_KEYS if k in tab]
            if len(given) == 1:
                missing = next(k for k in _EXTENT_KEYS if k not in tab)
                raise ValueError(f"missing key {where}.{missing} ({where}.{given[0]} needs it: a mirror's "
                                 f"extent is along_mm and height_mm)")
            if given:
                kwargs[f"{name}_extent"] = _build(
                    MirrorExtent, where, along_mm=_pair(tab["along_mm"], f"{where}.along_mm"),
                    height_mm=_pair(tab["height_mm"], f"{where}.height_mm"))
            if "tilt_deg" in tab or "shift_mm" in tab:
                tilt = _degrees_to_rad(_pair(tab.get("tilt_deg", [0.0, 0.0]), f"{where}.tilt_deg"), f"{where}.tilt_deg")
                kwargs[f"{name}_error"] = _build(MirrorError, where, tilt_rad=tilt, shift_mm=tab.get("shift_mm", 0.0))
    mirrors = _build(Mirrors, "mirrors", **kwargs)
    rig = Rig(camera, mirrors, calibration)
    check_rig_bounds(rig, "distortion_k" if "distortion_k" in cam_t else "distortion")
    return rig


def _build(cls, where: str, **kwargs):
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:
        msg = str(exc).replace("tilt_rad", "tilt_deg").replace("box_rotation_rad", "box_rotation_deg")
        raise type(exc)(f"{where}.{msg}") from None


def rig_to_dict(rig: Rig) -> dict:
    """The nested dict of a rig file (angles in degrees); inverse of :func:`rig_from_dict`."""
    c, m = rig.camera, rig.mirrors
    mirrors = {
        "baseline_mm": m.baseline_mm,
        "m1_axis_distance_mm": m.m1_axis_distance_mm,
        "m2_axis_distance_mm": m.m2_axis_distance_mm,
        "angle_deg": math.degrees(m.angle_rad),
        "plate_thickness_mm": m.plate_thickness_mm,
        "refractive_index": m.refractive_index,
        "split_ratio": m.split_ratio,
    }
    for k in ("refraction_l_mm", "refraction_m_mm"):
        if getattr(m, k) is not None:
            mirrors[k] = float(getattr(m, k))
    if m.box_rotation_rad != (0.0, 0.0, 0.0):
        mirrors["box_rotation_deg"] = [_deg_out(r) for r in m.box_rotation_rad]
    for name in MIRROR_NAMES:
        ext, err = m.extent(name), m.error(name)
        table = {}
        if ext is not None:
            table.update(along_mm=list(ext.along_mm), height_mm=list(ext.height_mm))
        if not err.is_zero:
            table.update(tilt_deg=[_deg_out(t) for t in err.tilt_rad], shift_mm=err.shift_mm)
        if table:
            mirrors[name] = table
    dist = c.distortion
    lens = {"distortion": list(dist)} if c.distorted else {}     # the current key (distortion_k: older files')
    cal = rig.calibration
    calibration = {} if cal is None else {"calibration": {
        "rms_px": cal.rms_px, "rms_left_px": cal.rms_left_px, "rms_right_px": cal.rms_right_px,
        "images": cal.images, "kinds": cal.kinds}}
    return _plain({
        "camera": {
            "focal_length_mm": c.focal_length_mm,
            "pixel_pitch_mm": list(c.pixel_pitch_mm),
            "image_size_px": list(c.image_size_px),
            "principal_point_px": list(c.principal_point_px),
            **lens,
            **({"relative_illumination": list(c.relative_illumination)} if c.vignetted else {}),
        },
        "mirrors": mirrors,
        **calibration,
    })


def rig_digest(rig: Rig) -> str:
    """SHA-256 (64 hex digits) of a rig's geometry: every value of its camera and mirrors as
    :func:`rig_to_dict` writes them (floats exactly; its calibration's statistics left out). A file fitted or
    triangulated through one rig names it by this, so that a reader can tell another rig's values from its own
    (a hand-eye mount calibrated through another camera used without a word: an adversarial trial)."""
    import hashlib
    values = {k: v for k, v in rig_to_dict(rig).items() if k != "calibration"}
    return hashlib.sha256(json.dumps(values, sort_keys=True).encode()).hexdigest()


def _plain(value):
    """The dict with every number a plain Python int or float (a rig may hold NumPy scalars, e.g. from a
    calibration; TOML and JSON writers must never see them)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, bool) or isinstance(value, str):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    return float(value)


def dumps_rig(rig: Rig, fmt: str = "toml", template: str | None = None) -> str:
    """A rig file's text, ``fmt`` 'toml' or 'json'.

    With ``template``, the text of a TOML rig file (e.g. the nominal rig a calibration started from), the
    TOML is that text with the rig's values in it: its comments, key order and layout stay wherever a value
    is unchanged, changed values are replaced in place (their comments kept), keys the rig no longer has
    are removed and new ones appended to their table (:func:`psvs.io.tomlfile.update_toml`). JSON has no
    comments: ``template`` is ignored there. A rig with a value outside :mod:`psvs.optics.bounds` is refused
    (ValueError naming the key): psvs never writes a rig file it would not read back.
    """
    check_rig_bounds(rig, memory=False)
    data = rig_to_dict(rig)
    if fmt == "json":
        return json.dumps(data, indent=2) + "\n"
    if fmt != "toml":
        raise ValueError(f"fmt must be 'toml' or 'json', got {fmt!r}")
    return dumps_toml(data) if template is None else update_toml(template, data, "TOML rig template")


def save_rig(rig: Rig, path, template: str | None = None) -> None:
    """Write a rig file atomically; the format follows the suffix (.json, else TOML), a TOML file in the
    comments and layout of ``template`` when given (:func:`dumps_rig`)."""
    path = Path(path)
    write_atomic(path, dumps_rig(rig, "json" if path.suffix.lower() == ".json" else "toml", template))


def rig_template(path) -> str | None:
    """The text of the rig file a ``--rig`` argument names (:func:`rig_path`: a shipped rig's own file for its
    name), for :func:`save_rig` to keep its comments and layout; None for a JSON rig file (no comments)."""
    path = rig_path(path)
    if path.suffix.lower() == ".json":
        return None
    return read_text(path, "TOML")
