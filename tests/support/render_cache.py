"""The test session's renders kept by content (a pytest plugin of the root conftest).

A test that renders a scene another test of the session rendered through the same rig (a module's frames at
the same seed, a parametrized test's shared scene, the README's examples beside the docs') reads the views
from the session's shared folder (tests/support/shared_files.py, seen by every xdist worker) instead of
tracing them again: :func:`psvs.simulate.render.render_views` and :func:`psvs.simulate.render.ground_truth`
answer from files named by a hash of what they depend on (the scene, the rig, the samples per pixel, adaptive
or not), made by the first caller under the file's lock. The renderer is deterministic, so what is read is
what would have been traced (tests/simulate/test_render_cache.py compares them). The renderer's own refusals
(the memory a render needs, a scene behind the rig's front) are made first, kept or not.

Not kept: a render through a moved geometry (a camera moving through a scene: its hits are the moved
scene's only to float64's rounding), a scene or rig that does not pickle, and the renders of a test marked
``fresh_render`` (one that compares a render with another of the same scene, e.g. on another thread count).
"""
from __future__ import annotations

import dataclasses
import hashlib
import pickle
from pathlib import Path

import numpy as np
import pytest

from tests.support.shared_files import shared_file

_FRESH = {"on": False}


def content_key(*parts) -> str | None:
    """A hash of ``parts`` (pickled), or None when one of them does not pickle."""
    try:
        blob = pickle.dumps(parts, protocol=5)
    except Exception:            # noqa: BLE001 - whatever keeps it from pickling: traced, not kept
        return None
    return hashlib.sha256(blob).hexdigest()[:32]


def _saved(path: Path, arrays: dict) -> None:
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def _load(path: Path) -> dict:
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def cached_views(original):
    """``render_views`` kept by content (module docstring)."""
    from psvs.simulate.geometry import SceneGeometry
    from psvs.simulate.render import check_scene_in_front, check_supersample

    def render_views(scene, rig, supersample=2, geom=None, adaptive=False):
        own = geom is None or type(geom) is SceneGeometry
        key = content_key("views", scene, rig, supersample, bool(adaptive)) if own and not _FRESH["on"] else None
        if key is None:
            return original(scene, rig, supersample, geom, adaptive)
        # the renderer's refusals first, as it makes them: the memory a render needs (a test of the guard sets its
        # own limit) and a scene before the rig
        check_supersample(rig, supersample)
        check_scene_in_front(geom or SceneGeometry(scene), rig)

        def make(path):
            left, right = original(scene, rig, supersample, geom, adaptive)
            _saved(path, {"left": left, "right": right})

        views = _load(shared_file(f"views-{key}.npz", make))
        return views["left"], views["right"]

    render_views.__doc__, render_views.original = original.__doc__, original
    return render_views


def cached_truth(original):
    """``ground_truth`` kept by content (module docstring)."""
    from psvs.simulate.geometry import SceneGeometry
    from psvs.simulate.render import GroundTruth
    names = [f.name for f in dataclasses.fields(GroundTruth)]

    def ground_truth(scene, rig, geom=None):
        own = geom is None or type(geom) is SceneGeometry
        key = content_key("truth", scene, rig) if own and not _FRESH["on"] else None
        if key is None:
            return original(scene, rig, geom)

        def make(path):
            truth = original(scene, rig, geom)
            _saved(path, {f: getattr(truth, f) for f in names})

        return GroundTruth(**_load(shared_file(f"truth-{key}.npz", make)))

    ground_truth.__doc__, ground_truth.original = original.__doc__, original
    return ground_truth


def pytest_configure(config):
    """The renderer's two costly calls replaced by their kept forms for the session (the module's names, which
    ``render`` and every caller look up when they call)."""
    config.addinivalue_line("markers", "fresh_render: the test's renders are traced, never read from the "
                                       "session's kept renders (tests/support/render_cache.py)")
    import psvs.simulate.render as render
    if not hasattr(render.render_views, "original"):
        render.render_views = cached_views(render.render_views)
        render.ground_truth = cached_truth(render.ground_truth)


@pytest.fixture(autouse=True)
def _fresh_renders(request):
    """A test marked ``fresh_render`` traces its renders."""
    _FRESH["on"] = request.node.get_closest_marker("fresh_render") is not None
    yield
    _FRESH["on"] = False
