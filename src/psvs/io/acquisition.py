"""A camera's acquisition settings in TOML: the rig file's optional ``[camera.acquisition]`` table (how the
rig's machine-vision camera takes its frames) and the ``camera.toml`` a live or capture run records beside
its output (docs/cameras.md)::

    [camera.acquisition]
    exposure_us = 2000.0
    gain_db = 0.0
    frame_rate_hz = 30.0
    pixel_format = "Mono12"
    trigger = "software"           # or "line1"; absent: free run
    auto_exposure = false
    auto_gain = false
    settings_file = "ace.pfs"      # relative to the rig file
    [camera.acquisition.features]  # any feature, set in this order, last
    BlackLevel = "0"
"""
from __future__ import annotations

from pathlib import Path

from psvs.io.atomic import write_atomic
from psvs.io.schema import Field, read_fields
from psvs.io.tomlfile import load_toml

NUMBERS = ("exposure_us", "gain_db", "frame_rate_hz")
STRINGS = ("pixel_format", "trigger", "settings_file")
FLAGS = ("auto_exposure", "auto_gain")
#: What a recording's table also says of the camera, read back but not applied.
INFO = ("camera", "serial", "bits", "source")
#: The table's schema (:mod:`psvs.io.schema`); ``features``: any feature NAME = value, set in this order.
FIELDS = ({k: Field("number") for k in NUMBERS} | {k: Field("string") for k in STRINGS}
          | {k: Field("flag") for k in FLAGS} | {k: Field("any") for k in INFO}
          | {"features": Field("table", note="of NAME = value", default={})})


def acquisition_from_table(table, where: str, folder: Path | None = None) -> dict:
    """The keyword arguments of :class:`psvs.live.camera.Acquisition` a table gives (checked: one-line
    ValueError/TypeError naming ``where``.key); ``settings_file`` relative to ``folder``."""
    out = {k: v for k, v in read_fields(table, where, FIELDS).items() if k not in INFO}
    if "settings_file" in out and folder is not None:
        out["settings_file"] = str(folder / out["settings_file"])
    out["features"] = tuple((str(k), _text(v)) for k, v in out["features"].items())
    return out


def _text(v) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else str(v)


def load_acquisition(rig_file) -> dict:
    """The ``[camera.acquisition]`` table of a rig file as :func:`acquisition_from_table` gives it ({} when the
    file has none)."""
    path = Path(rig_file)
    cam = load_toml(path, "rig").get("camera", {})
    if not isinstance(cam, dict) or "acquisition" not in cam:
        return {}
    try:
        return acquisition_from_table(cam["acquisition"], "camera.acquisition", path.parent)
    except (ValueError, TypeError) as exc:
        raise type(exc)(f"{path}: {exc}") from None


def dumps_acquisition(settings: dict) -> str:
    """A ``[camera.acquisition]`` TOML table of the settings a source reports (scalars; a nested dict
    ``features`` as its own table)."""
    import tomlkit
    doc = tomlkit.document()
    doc.add(tomlkit.comment("How each frame of this recording was taken (psvs; docs/cameras.md)"))
    acq = tomlkit.table()
    for k, v in settings.items():
        if k != "features" and v is not None:
            acq.add(k, v)
    if settings.get("features"):
        feats = tomlkit.table()
        for k, v in settings["features"].items():
            feats.add(k, v)
        acq.add("features", feats)
    cam = tomlkit.table()
    cam.add("acquisition", acq)
    doc.add("camera", cam)
    return tomlkit.dumps(doc)


def write_acquisition(path, settings: dict) -> None:
    """Write the acquisition ``settings`` to ``path`` as TOML (:func:`dumps_acquisition`), atomically."""
    write_atomic(path, dumps_acquisition(settings))
