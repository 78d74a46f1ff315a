"""The test session's kept renders (tests/support/render_cache.py): what a kept render reads back is what the
renderer traces, bit for bit; a render through a moved geometry, a test marked ``fresh_render`` and a scene
that does not pickle are traced."""
import numpy as np
import pytest

import psvs.simulate.render as render_module
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.geometry import SceneGeometry
from psvs.simulate.render import render
from tests.support.render_cache import content_key
from tests.support.shared_files import session_folder


def _kept_files(prefix: str) -> set[str]:
    folder = session_folder()
    return {p.name for p in folder.glob(f"{prefix}-*.npz")} if folder.exists() else set()


def test_a_kept_render_is_the_traced_one(small_rig):
    """Views and truth read back from the session's files equal, bit for bit, a trace of the same scene made
    now; the second render of the scene reads its files and writes none; the arrays are the caller's own."""
    scene = builtin_scene("fig5b")
    views, truth = render_module.render_views, render_module.ground_truth
    assert hasattr(views, "original") and hasattr(truth, "original")
    first = render(scene, small_rig, truth=True, supersample=1)
    own = [session_folder() / f"views-{content_key('views', scene, small_rig, 1, False)}.npz",
           session_folder() / f"truth-{content_key('truth', scene, small_rig)}.npz"]
    made = [p.stat().st_mtime_ns for p in own]            # this scene's files (the other worker makes its own)
    again = render(scene, small_rig, truth=True, supersample=1)
    assert [p.stat().st_mtime_ns for p in own] == made    # read, not made again
    traced = views.original(scene, small_rig, 1, SceneGeometry(scene), False)
    truth_traced = truth.original(scene, small_rig)
    for a, b in zip((first.left, first.right), traced, strict=True):
        np.testing.assert_array_equal(a, b)
    for name in ("depth_left_mm", "disparity_left_px", "valid_right"):
        np.testing.assert_array_equal(getattr(again.truth, name), getattr(truth_traced, name))
    np.testing.assert_array_equal(first.image, again.image)
    again.left[0, 0] = -1.0                      # the caller's own array: the next read is untouched
    assert render(scene, small_rig, supersample=1).left[0, 0] == first.left[0, 0]


@pytest.mark.fresh_render
def test_a_test_marked_fresh_traces(small_rig):
    """Marked ``fresh_render``: a scene no test rendered yet leaves no file."""
    scene = builtin_scene("fig5b:distance_mm=517")
    render(scene, small_rig, supersample=1)
    assert f"views-{content_key('views', scene, small_rig, 1, False)}.npz" not in _kept_files("views")


def test_what_does_not_pickle_has_no_key():
    assert content_key("views", lambda x: x) is None
    assert content_key("views", 1.0, np.arange(3)) == content_key("views", 1.0, np.arange(3))
    assert content_key("views", 1.0, np.arange(3)) != content_key("views", 1.0, np.arange(4))
