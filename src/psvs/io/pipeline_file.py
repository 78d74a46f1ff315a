"""Pipeline files (TOML) <-> :class:`psvs.imaging.pipeline.Pipeline`.

    [[steps]]
    op = "median"
    ksize = 3
    [[steps]]
    op = "threshold"
    level = 92
    [[steps]]
    op = "roberts"
"""
from __future__ import annotations

from pathlib import Path

from psvs.imaging.pipeline import Pipeline, make_pipeline
from psvs.io.tomlfile import load_toml


def load_pipeline(path) -> Pipeline:
    """The pipeline of a pipeline file; errors name the file and the step."""
    path = Path(path)
    data = load_toml(path, "pipeline")
    if set(data) != {"steps"} or not isinstance(data["steps"], list):
        raise ValueError(f"{path}: a pipeline file holds one array of tables [[steps]]")
    try:
        return make_pipeline(data["steps"])
    except (ValueError, TypeError) as exc:
        raise type(exc)(f"{path}: {exc}") from None
