"""Reproducible recordings: a ``live`` or ``capture`` run from a camera writes the camera's settings beside
its output (``NAME.camera.toml``, the ``[camera.acquisition]`` table in effect, and ``NAME.camera.pfs``, the
camera's whole feature file as pylon Viewer saves it), so a later replay knows how each frame was taken."""
from __future__ import annotations

from pathlib import Path


def settings_paths(args, out: Path | None, folder: Path | None = None) -> dict:
    """The settings files a camera run writes (option -> path; {} for a video, or a run that writes nothing):
    in ``folder`` as camera.toml/.pfs, else beside ``out`` (or --mcap) as OUT.camera.toml/.pfs."""
    if getattr(args, "camera", None) is None:
        return {}
    if folder is not None:
        return {"-o (its camera.toml)": folder / "camera.toml", "-o (its camera.pfs)": folder / "camera.pfs"}
    base = out if out is not None else (Path(args.mcap) if getattr(args, "mcap", None) else None)
    if base is None:
        return {}
    stem = base.with_suffix("")
    return {f"{base} (its camera settings)": Path(f"{stem}.camera.toml"),
            f"{base} (its camera feature file)": Path(f"{stem}.camera.pfs")}


def record_settings(args, out: Path | None, source, folder: Path | None = None) -> list[Path]:
    """Write the source's settings where :func:`settings_paths` says (the .pfs only when the camera has a
    feature file); the paths written."""
    from psvs.io.acquisition import write_acquisition
    from psvs.io.atomic import write_atomic
    paths = list(settings_paths(args, out, folder).values())
    if not paths:
        return []
    toml_path, pfs_path = paths
    write_acquisition(toml_path, source.settings())
    written = [toml_path]
    text = source.feature_file()
    if text is not None:
        write_atomic(pfs_path, text)
        written.append(pfs_path)
    return written
